"""Where the fast engine's compiled code is cached, and the ``jit`` decorators that use it.

The fast engine (the package `gearpair.fast`) is compiled with numba, and its entry points
are cached on disk (``cache=True``; the functions they call are compiled into them, see
`gearpair.jitlink`). Unless ``NUMBA_CACHE_DIR`` is set, the cache lives in a per-user
directory (``$XDG_CACHE_HOME/gearpair/numba``, ``~/.cache/gearpair/numba``, or
``%LOCALAPPDATA%/gearpair/numba``) keyed by the content of the engine's source files rather
than their location, so a copy of the package extracted to a fresh temporary directory (an
FMU instantiation) finds the code compiled by an earlier one. If no cache directory can be
used, the functions are compiled in memory on first use.

This module must be imported before numba (it sets ``NUMBA_CACHE_DIR``); the engine imports
`jit_entry`, `jit` and `jit_hot` from here.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time

from .shipped import FORMAT, MANIFEST, SHIPPED_FOLDER, user_cache_dir

CACHE_DIR = user_cache_dir()
if CACHE_DIR is not None and "numba" not in sys.modules:
    os.environ.setdefault("NUMBA_CACHE_DIR", CACHE_DIR)

import numba  # noqa: E402  (after NUMBA_CACHE_DIR is set)

from . import jitlink  # noqa: E402  (imports numba)

_PACKAGE = __name__.rpartition(".")[0]  # "gearpair", or "_gearpair_fmu" inside the FMU
ENGINE_MODULE = _PACKAGE + ".fast"  # the engine: this module, or a package of modules
_HERE = os.path.dirname(os.path.abspath(__file__))


def engine_files(root: str = _HERE) -> list[str]:
    """The engine's source files under a package folder: ``fast.py`` or ``fast/*.py``
    (sorted), plus this file and `jitlink`, whose options shape the compiled code, and
    `stepblock`, whose slots the compiled step reads."""
    pkg = os.path.join(root, "fast")
    if os.path.isdir(pkg):
        files = sorted(os.path.join(pkg, n) for n in os.listdir(pkg) if n.endswith(".py"))
    else:
        files = [pkg + ".py"]
    extra = [os.path.join(root, n) for n in ("jitcache.py", "jitlink.py", "stepblock.py")]
    return files + [p for p in extra if os.path.isfile(p)]


def _file_digest(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha1(fh.read()).hexdigest()


def _engine_key() -> str:
    """sha1 (20 hex digits) of the engine files' contents, numba's version and the engine's
    module name: the name of this package's folder in the cache and of its shipped code."""
    own = sorted((os.path.basename(p), _file_digest(p)) for p in engine_files())
    return hashlib.sha1("\n".join(f"{n} {d}" for n, d in own).encode()
                        + numba.__version__.encode() + ENGINE_MODULE.encode()).hexdigest()[:20]


try:
    KEY: str | None = _engine_key()
except OSError:  # a source file cannot be read: no disk cache, no shipped code
    KEY = None

# -- compiled code shipped with the package (an FMU's copy; `gearpair.shipped`) ----------------
SHIPPED_DIR = os.path.join(_HERE, SHIPPED_FOLDER)


def python_tag() -> str:
    """The interpreter as compiled code depends on it (implementation, version, ABI)."""
    return (f"{sys.implementation.name}-{sys.version_info[0]}.{sys.version_info[1]}"
            f"{getattr(sys, 'abiflags', '')}")


def _versions() -> dict[str, str]:
    """What compiled code depends on besides the engine's sources and the CPU."""
    import llvmlite
    import numpy

    return {"python": python_tag(), "numba": numba.__version__,
            "llvmlite": llvmlite.__version__, "numpy": numpy.__version__}


def _host_features() -> set[str]:
    from llvmlite import binding as ll

    return {name for name, on in ll.get_host_cpu_features().items() if on}


def _check_shipped(path: str = SHIPPED_DIR) -> tuple[tuple | None, str]:
    """(numba's codegen "magic tuple" of the shipped code, "") if the code in ``path`` was
    compiled for this engine, these versions and a CPU this host can run; else (None, why)."""
    if os.environ.get("GEARPAIR_SHIPPED_CODE", "1").strip().lower() in ("0", "off", "no"):
        return None, "GEARPAIR_SHIPPED_CODE=0"
    try:
        with open(os.path.join(path, MANIFEST), encoding="utf-8") as fh:
            m = json.load(fh)
    except FileNotFoundError:
        return None, "no compiled code shipped"
    except (OSError, ValueError) as e:
        return None, f"unreadable manifest of the shipped code ({e})"
    try:
        if m.get("format") != FORMAT or m.get("key") != KEY or \
                m.get("engine_module") != ENGINE_MODULE:
            return None, "the shipped code is for other engine sources or another numba"
        host = _versions()
        diff = [f"{k} {m['versions'].get(k)} (here {v})" for k, v in host.items()
                if m["versions"].get(k) != v]
        if diff:
            return None, "the shipped code is for " + ", ".join(diff)
        from llvmlite import binding as ll

        if m["triple"] != ll.get_process_triple():
            return None, f"the shipped code is for {m['triple']} (here {ll.get_process_triple()})"
        missing = sorted(set(m["requires"]) - _host_features())
        if missing:
            return None, (f"the shipped code is for CPU {m['cpu_name']}; this CPU lacks "
                          + ", ".join(missing))
        return tuple(m["magic"]), ""
    except Exception as e:  # noqa: BLE001 - a malformed manifest: compile instead
        return None, f"unusable manifest of the shipped code ({type(e).__name__}: {e})"


SHIPPED_MAGIC, SHIPPED_WHY = _check_shipped() if KEY is not None else (None, "no engine key")
# numba internals this module found changed, and the fallback taken (`missing_internals`)
FALLBACKS: dict[str, str] = {}
# how the engine's functions were obtained in this process: from the shipped code, from the
# user cache, or compiled (a count per compiled function and signature)
STATS = {"shipped": 0, "cached": 0, "compiled": 0}
_NOTICE = {"given": False}


def _announce_compile() -> None:
    """Tell a command-line user that the first run compiles (``GEARPAIR_COMPILE_NOTICE``
    set, as `gearpair.cli` does); once per process."""
    if _NOTICE["given"] or not os.environ.get("GEARPAIR_COMPILE_NOTICE"):
        return
    _NOTICE["given"] = True
    where = f"; later runs load it from {CACHE_PATH}" if CACHE_PATH else ""
    print(f"gearpair: compiling the fast engine once (20-30 s){where}",
          file=sys.stderr, flush=True)


def _install_locator() -> bool:
    """Key the cache of the engine's functions by file content, not by directory.

    numba keys a cache directory by the absolute path of the source file, so a package
    extracted to a new temporary directory would recompile. This locator puts the functions
    of the engine's files (`engine_files`) under ``<cache dir>/gearpair_fast_<KEY>``, the key
    a sha1 of the files' contents, numba's version and the engine's module name; numba itself
    still checks each file's content hash (its source stamp). The module name is part of the
    key because a cached function names its module, which numba imports on loading it: the
    FMU's bundled copy (``_gearpair_fmu.fast``) must not load entries of ``gearpair.fast``
    and so import a host's package. Returns whether caching can be used.
    """
    if CACHE_DIR is None or KEY is None:
        return False
    try:
        from numba.core import caching

        files = engine_files()
        own = {os.path.basename(p): _file_digest(p) for p in files}
        digest = KEY
        where = CACHE_PATH
        # path -> holds one of the engine's files (by content)
        same: dict[str, bool] = {os.path.abspath(p): True for p in files}

        class _ContentLocator(caching.UserProvidedCacheLocator):
            _gearpair_digest = digest

            def __init__(self, py_func, py_file):
                super().__init__(py_func, py_file)
                self._cache_path = where

            @classmethod
            def from_function(cls, py_func, py_file):
                # A host that deletes an extracted FMU and loads the next copy from a new
                # folder imports the engine again under another path: match by content.
                if not _is_engine_module(getattr(py_func, "__module__", None)):
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
    except Exception as e:  # noqa: BLE001 - numba internals changed: its default locators remain
        FALLBACKS["cache keyed by content"] = f"{type(e).__name__}: {e}"
        return bool(numba.config.CACHE_DIR)


def _is_engine_module(name) -> bool:
    return isinstance(name, str) and (name == ENGINE_MODULE or
                                      name.startswith(ENGINE_MODULE + "."))


CACHE_PATH = os.path.join(CACHE_DIR, "gearpair_fast_" + KEY) if CACHE_DIR and KEY else None
CACHE = _install_locator()


def _engine_cache_class():
    """numba's per-function disk cache, consulting the shipped code first (read only).

    The shipped index files are numba's own, written at build time for a portable CPU; their
    keys hold that CPU's codegen tuple where a lookup on this host would use the host's, so
    the lookup here asks for the shipped tuple once `_check_shipped` found that this CPU runs
    the code. Anything not found there (or unreadable) comes from the user cache or is
    compiled and saved into the user cache, as without shipped code.
    """
    from numba.core import caching

    class _EngineCache(caching.FunctionCache):
        def __init__(self, py_func):
            super().__init__(py_func)
            self._shipped = None
            if SHIPPED_MAGIC is not None:
                self._shipped = caching.IndexDataCacheFile(
                    cache_path=SHIPPED_DIR, filename_base=self._impl.filename_base,
                    source_stamp=self._impl.locator.get_source_stamp())

        def load_overload(self, sig, target_context):
            if self._shipped is not None:
                try:
                    target_context.refresh()
                    key = self._index_key(sig, target_context.codegen())
                    data = self._shipped.load((key[0], SHIPPED_MAGIC) + tuple(key[2:]))
                    if data is not None:
                        cres = self._impl.rebuild(target_context, data)
                        STATS["shipped"] += 1
                        return cres
                except AttributeError as e:  # numba's cache internals changed
                    FALLBACKS["shipped code lookup"] = f"AttributeError: {e}"
                except Exception:  # noqa: BLE001 - damaged shipped files: the user cache
                    pass
            cres = super().load_overload(sig, target_context)
            if cres is None:
                STATS["compiled"] += 1
                _announce_compile()
            else:
                STATS["cached"] += 1
            return cres

    return _EngineCache


_ENGINE_CACHE = _engine_cache_class() if CACHE else None
# forceinline is set on every function, so none inherits it from the caller being compiled
_OPTIONS = dict(cache=CACHE, fastmath=False, error_model="numpy", _nrt=False,
                forceinline=False)
# Only the entry points (`jit_entry`) are called from Python. The others are called from
# compiled code alone: no wrapper converting Python arguments (for the records, the unboxing
# of some 30 arrays: code to generate and compile for every function), no C-callable one,
# and compiled to LLVM IR only (`jitlink`), so not cached on their own.
_INTERNAL = dict(_OPTIONS, no_cpython_wrapper=True, no_cfunc_wrapper=True)
if jitlink.LINK_ONLY is not None:
    _INTERNAL.update(cache=False, pipeline_class=jitlink.LINK_ONLY)


def _with_engine_cache(dispatcher):
    """Give a dispatcher that caches on disk the `_engine_cache_class` cache instead."""
    from numba.core.caching import FunctionCache

    if _ENGINE_CACHE is not None and type(getattr(dispatcher, "_cache", None)) is FunctionCache:
        try:
            dispatcher._cache = _ENGINE_CACHE(dispatcher.py_func)
        except Exception as e:  # noqa: BLE001 - keep numba's own cache
            FALLBACKS["shipped code cache"] = f"{type(e).__name__}: {e}"
    return dispatcher


# numba's caching internals that `_install_locator` and `_engine_cache_class` use
_CACHING_INTERNALS = {"CacheImpl": ("_locator_classes",), "UserProvidedCacheLocator": (),
                      "FunctionCache": ("_index_key", "load_overload"),
                      "IndexDataCacheFile": ("load",)}


def missing_internals() -> list[str]:
    """numba internals that the engine's compile (`jitlink`) and cache (this module) use and
    this numba lacks, each with the fallback it caused: [] when everything works as designed.
    The fallbacks keep the engine correct (numba's default compile and cache), but slower to
    compile or to start, so the test suite fails while one is active."""
    from numba.core import caching

    out = jitlink.missing_internals()
    for cls, attrs in _CACHING_INTERNALS.items():
        obj = getattr(caching, cls, None)
        if obj is None:
            out.append(f"jitcache: numba.core.caching.{cls} is missing")
        out += [f"jitcache: numba.core.caching.{cls}.{a} is missing" for a in attrs
                if obj is not None and not hasattr(obj, a)]
    out += [f"jitcache: {what} falls back to numba's own ({why})"
            for what, why in FALLBACKS.items()]
    return out


def jit_entry(func):
    """``numba.njit`` with the engine's options and cache, for the entry points: the only
    functions called from Python, each compiled with everything it calls inlined or
    linked, and cached."""
    return _with_engine_cache(numba.njit(**_OPTIONS)(func))


def jit(func):
    """An internal function of the engine (called from compiled code only), compiled once
    and linked into its callers, where LLVM decides whether to inline it: for code that
    runs per event, per piece or per pair change rather than per Runge-Kutta stage."""
    return jitlink.compiled_only(_with_engine_cache(numba.njit(**_INTERNAL)(func)))


def jit_hot(func):
    """`jit` that LLVM always inlines into its callers (numba's ``forceinline``), for the
    hot path and the small helpers: a call would pass every array of the records by value
    (some 230 machine words for the three records), more than a small helper's arithmetic.

    Each is typed and lowered once, whatever the number of its call sites; numba's own
    IR-level inlining (``inline="always"``) types the callee again at every call site,
    nested, which made a first compile take minutes.
    """
    return jitlink.compiled_only(
        _with_engine_cache(numba.njit(**dict(_INTERNAL, forceinline=True))(func)))


_LOADED: dict = {}


def load_engine() -> dict:
    """Load (or compile) every compiled entry point of the engine now, once per process.

    Runs a default `FastEngine` through what its users call (``reset``, ``output_values``
    of a fresh and of an advanced state, ``advance_values`` with and without a load speed,
    ``restore``, ``energy``, ``run``) for a few microseconds of model time, so that no
    later call compiles. Returns a report (the same dict on later calls, with
    ``first`` False): ``source`` "shipped" (the code shipped with this package copy), "cache"
    (the user cache), "compiled" (at least one function compiled now and saved in the user
    cache) or "memory" (compiled, no disk cache usable); ``seconds`` it took; ``counts`` per
    source; ``cache_dir`` (the user cache folder of this engine, or None); ``shipped_why``
    (why shipped code was not used, "" if it was usable).
    """
    if _LOADED:
        return dict(_LOADED, first=False)
    import importlib

    before = dict(STATS)
    t0 = time.perf_counter()
    fast = importlib.import_module(ENGINE_MODULE)
    eng = fast.FastEngine()
    eng.reset(torque=1000.0, speed=10.0)
    eng.output_values()  # a fresh state's outputs (an FMU's initialization)
    saved = eng.snapshot()
    eng.advance_values(2e-6, 1000.0, 10.0)
    eng.output_values()
    eng.advance_values(4e-6, 1000.0, 10.0, 10.0 / 2.4)  # a load speed (a driveline FMU)
    eng.restore(saved)
    eng.output_values()
    eng.energy()
    eng.run([eng.time, eng.time + 2e-6], 1000.0, 10.0)
    eng.run([eng.time, eng.time + 2e-6], 1000.0, 10.0, 10.0 / 2.4)
    # the exact propagator is compiled only for the engines that use it (`fast.loop.segment`)
    effects = importlib.import_module(_PACKAGE + ".effects")
    lti = fast.FastEngine(effects=effects.Effects(friction="off", stiffness="constant"))
    lti.reset(torque=1000.0, speed=10.0)
    lti.advance_values(2e-6, 1000.0, 10.0)
    lti.output_values()
    lti.run([lti.time, lti.time + 2e-6], 1000.0, 10.0)
    seconds = time.perf_counter() - t0
    counts = {k: STATS[k] - before[k] for k in STATS}
    if not CACHE:
        source = "memory"
    elif counts["compiled"]:
        source = "compiled"
    elif counts["shipped"] and not counts["cached"]:
        source = "shipped"
    else:
        source = "cache"
    _LOADED.update(source=source, seconds=seconds, counts=counts, cache_dir=CACHE_PATH,
                   shipped_why=SHIPPED_WHY, first=True)
    return dict(_LOADED)


def describe(report: dict, package: str = "this package") -> str:
    """One sentence on how `load_engine` got the engine's code, for a log (``package``: what
    the shipped code came with)."""
    took = f"{report['seconds']:.1f} s"
    if report["source"] == "shipped":
        return f"fast engine: loaded the compiled code shipped in {package} in {took}"
    if report["source"] == "cache":
        return f"fast engine: loaded the compiled code from {report['cache_dir']} in {took}"
    why = f" ({report['shipped_why']})" if report["shipped_why"] else ""
    if report["source"] == "memory":
        return (f"fast engine: compiled in {took}{why}; no writable cache folder, so every "
                "new process compiles again")
    return (f"fast engine: compiled once for this machine in {took}{why}; later runs load "
            f"it from {report['cache_dir']}")
