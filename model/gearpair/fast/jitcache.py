"""The on-disk cache of the compiled engine, keyed by content rather than location.

Unless ``NUMBA_CACHE_DIR`` is set, the cache lives in a per-user directory
(``$XDG_CACHE_HOME/gearpair/numba``, ``~/.cache/gearpair/numba``, or
``%LOCALAPPDATA%/gearpair/numba``) keyed by the content of this package's modules rather than
their location, so a copy of the package extracted to a fresh temporary directory (an FMU
instantiation) finds the code compiled by an earlier one. If no cache directory can be used,
the functions are compiled in memory on first use.

Import this module before numba anywhere else: it sets ``NUMBA_CACHE_DIR``.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile


def _cache_dir() -> str | None:
    """A writable directory for numba's cache (NUMBA_CACHE_DIR or a per-user one), or None."""
    path = os.environ.get("NUMBA_CACHE_DIR")
    if not path:
        home = os.path.expanduser("~")
        if sys.platform.startswith("win"):
            base = os.environ.get("LOCALAPPDATA") or os.path.join(home, "AppData", "Local")
        elif sys.platform == "darwin":
            base = os.path.join(home, "Library", "Caches")
        else:
            base = os.environ.get("XDG_CACHE_HOME") or os.path.join(home, ".cache")
        path = os.path.join(base, "gearpair", "numba")
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except Exception:  # noqa: BLE001 - any failure means: no disk cache
        return None
    return path


CACHE_DIR = _cache_dir()
if CACHE_DIR is not None and "numba" not in sys.modules:
    os.environ.setdefault("NUMBA_CACHE_DIR", CACHE_DIR)

import numba  # noqa: E402  (after NUMBA_CACHE_DIR is set)

PACKAGE = __name__.rpartition(".")[0]  # gearpair.fast, or the FMU's _gearpair_fmu.fast
HERE = os.path.dirname(os.path.abspath(__file__))


def package_digest(folder: str) -> str:
    """sha1 over every module of the package in ``folder`` (names and contents), numba's
    version and the package's import name."""
    h = hashlib.sha1()
    for name in sorted(os.listdir(folder)):
        if name.endswith(".py"):
            h.update(name.encode())
            with open(os.path.join(folder, name), "rb") as fh:
                h.update(fh.read())
    h.update(numba.__version__.encode() + PACKAGE.encode())
    return h.hexdigest()[:20]


def _install_locator() -> bool:
    """Key the cache of this package's functions by content, not by directory.

    numba keys a cache directory by the absolute path of the source file, so a package
    extracted to a new temporary directory would recompile. This locator puts the functions
    of the package under ``<cache dir>/gearpair_fast_<digest>`` (`package_digest`); numba
    itself still checks each file's content hash (its source stamp). The import name is part
    of the key because a cached function names its module, which numba imports on loading
    it: the FMU's bundled copy (``_gearpair_fmu.fast``) must not load entries of
    ``gearpair.fast`` and so import a host's package. Returns whether caching can be used.
    """
    if CACHE_DIR is None:
        return False
    try:
        from numba.core import caching

        digest = package_digest(HERE)
        where = os.path.join(CACHE_DIR, "gearpair_fast_" + digest)
        same: dict[str, bool] = {HERE: True}  # folder -> holds this very package (by content)

        class _ContentLocator(caching.UserProvidedCacheLocator):
            _gearpair_digest = digest

            def __init__(self, py_func, py_file):
                super().__init__(py_func, py_file)
                self._cache_path = where

            @classmethod
            def from_function(cls, py_func, py_file):
                # A host that deletes an extracted FMU and loads the next copy from a new
                # folder imports the package again under another path: match by content.
                module = getattr(py_func, "__module__", None) or ""
                if module.rpartition(".")[0] != PACKAGE:
                    return None  # another module, or this package under another import name
                folder = os.path.dirname(os.path.abspath(py_file))
                if folder not in same:
                    try:
                        same[folder] = package_digest(folder) == digest
                    except OSError:
                        same[folder] = False
                if not same[folder]:
                    return None  # other modules keep numba's own locators
                return super(caching.UserProvidedCacheLocator, cls).from_function(py_func,
                                                                                 py_file)

        classes = caching.CacheImpl._locator_classes
        if not any(getattr(c, "_gearpair_digest", None) == digest for c in classes):
            classes.insert(0, _ContentLocator)
        return True
    except Exception:  # noqa: BLE001 - numba internals changed: its default locators remain
        return bool(numba.config.CACHE_DIR)


CACHE = _install_locator()
jit = numba.njit(cache=CACHE, fastmath=False, error_model="numpy", _nrt=False)
# Hot helpers are inlined at numba IR level: a call between compiled functions passes every
# array of its records by value, which costs more than the arithmetic here.
jit_inline = numba.njit(cache=CACHE, fastmath=False, error_model="numpy", inline="always",
                        _nrt=False)


def inline_copy(func):
    """An inlined copy of compiled ``func`` for its hot call sites (the others keep calling
    the compiled function, which keeps their code small)."""
    return jit_inline(func.py_func)
