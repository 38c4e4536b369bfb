"""Where the fast engine's compiled code is cached, and the ``jit`` decorators that use it.

The fast engine (`gearpair.fast`, a module today, a package of several modules later) is
compiled with numba and cached on disk (``cache=True``). Unless ``NUMBA_CACHE_DIR`` is set, the
cache lives in a per-user directory (``$XDG_CACHE_HOME/gearpair/numba``,
``~/.cache/gearpair/numba``, or ``%LOCALAPPDATA%/gearpair/numba``) keyed by the content of the
engine's source files rather than their location, so a copy of the package extracted to a
fresh temporary directory (an FMU instantiation) finds the code compiled by an earlier one. If
no cache directory can be used, the functions are compiled in memory on first use.

This module must be imported before numba (it sets ``NUMBA_CACHE_DIR``); the engine imports
`jit` and `jit_inline` from here.
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

_PACKAGE = __name__.rpartition(".")[0]  # "gearpair", or "_gearpair_fmu" inside the FMU
ENGINE_MODULE = _PACKAGE + ".fast"  # the engine: this module, or a package of modules
_HERE = os.path.dirname(os.path.abspath(__file__))


def engine_files(root: str = _HERE) -> list[str]:
    """The engine's source files under a package folder: ``fast.py`` or ``fast/*.py``
    (sorted), plus this file, whose decorator options shape the compiled code."""
    pkg = os.path.join(root, "fast")
    if os.path.isdir(pkg):
        files = sorted(os.path.join(pkg, n) for n in os.listdir(pkg) if n.endswith(".py"))
    else:
        files = [pkg + ".py"]
    return files + [os.path.join(root, "jitcache.py")]


def _file_digest(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha1(fh.read()).hexdigest()


def _install_locator() -> bool:
    """Key the cache of the engine's functions by file content, not by directory.

    numba keys a cache directory by the absolute path of the source file, so a package
    extracted to a new temporary directory would recompile. This locator puts the functions
    of the engine's files (`engine_files`) under ``<cache dir>/gearpair_fast_<key>``, the key
    a sha1 of the files' contents, numba's version and the engine's module name; numba itself
    still checks each file's content hash (its source stamp). The module name is part of the
    key because a cached function names its module, which numba imports on loading it: the
    FMU's bundled copy (``_gearpair_fmu.fast``) must not load entries of ``gearpair.fast``
    and so import a host's package. Returns whether caching can be used.
    """
    if CACHE_DIR is None:
        return False
    try:
        from numba.core import caching

        files = engine_files()
        own = {os.path.basename(p): _file_digest(p) for p in files}
        digest = hashlib.sha1("\n".join(f"{n} {d}" for n, d in sorted(own.items())).encode()
                              + numba.__version__.encode()
                              + ENGINE_MODULE.encode()).hexdigest()[:20]
        where = os.path.join(CACHE_DIR, "gearpair_fast_" + digest)
        # path -> holds one of the engine's files (by content)
        same: dict[str, bool] = {os.path.abspath(p): True for p in files}

        def is_engine_module(name) -> bool:
            return isinstance(name, str) and (name == ENGINE_MODULE or
                                              name.startswith(ENGINE_MODULE + "."))

        class _ContentLocator(caching.UserProvidedCacheLocator):
            _gearpair_digest = digest

            def __init__(self, py_func, py_file):
                super().__init__(py_func, py_file)
                self._cache_path = where

            @classmethod
            def from_function(cls, py_func, py_file):
                # A host that deletes an extracted FMU and loads the next copy from a new
                # folder imports the engine again under another path: match by content.
                if not is_engine_module(getattr(py_func, "__module__", None)):
                    return None  # another module, or the engine under another import name
                path = os.path.abspath(py_file)
                if path not in same:
                    try:
                        same[path] = own.get(os.path.basename(path)) == _file_digest(path)
                    except OSError:
                        same[path] = False
                if not same[path]:
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
# array by value with reference counting, which costs more than the arithmetic here.
jit_inline = numba.njit(cache=CACHE, fastmath=False, error_model="numpy", inline="always",
                        _nrt=False)
