"""How the fast engine is compiled (a first compile of at most 30 s).

Only the entry points are called from Python and cached; every other function is compiled
to LLVM IR for its callers alone (`gearpair.jitlink`), so that LLVM optimizes and compiles
the engine once, at the entry point, instead of once per level of its call tree. The
results are the same bit for bit (`test_golden.py`); these tests hold the structure.
"""

from __future__ import annotations

import inspect
import subprocess
import sys

import numba
import pytest

from gearpair import jitcache, jitlink
from gearpair.fast import (
    contact,
    events,
    extremes,
    loop,
    lti,
    native,
    rk,
    setup,
    start,
    switching,
    views,
)

MODULES = (contact, events, extremes, loop, lti, native, rk, setup, start, switching, views)
ENTRIES = {"step_entry", "step_early_entry", "init_entry", "outputs_entry",
           "eval_entry", "reset_entry", "setup_entry", "compliances_entry"}


def dispatchers():
    """(module.name, dispatcher) of every compiled function of the engine."""
    out = []
    for mod in MODULES:
        for name, obj in inspect.getmembers(mod):
            if isinstance(obj, numba.core.dispatcher.Dispatcher) and \
                    obj.py_func.__module__ == mod.__name__:
                out.append((f"{mod.__name__.rsplit('.', 1)[1]}.{name}", obj))
    return out


def test_this_numba_compiles_internal_functions_to_ir_only():
    # if numba's internals change, jitlink falls back to numba's default (correct, slower
    # to compile): this test says so instead of letting the compile time creep back
    assert jitlink.LINK_ONLY is not None, jitlink.WHY


def test_no_fallback_for_other_numba_internals_is_active():
    """jitlink and jitcache fall back to numba's default compile and cache when numba's
    internals differ from those they were written for (correct, but a slower first compile,
    and a cache keyed by folder that an FMU extracted elsewhere does not find): CI must not
    pass on that fallback unnoticed."""
    jitcache.load_engine()  # every entry point, from the shipped code, the cache or compiled
    missing = jitcache.missing_internals()
    assert not missing, (f"numba {numba.__version__} lacks internals the fast engine's "
                         "compile and cache use: " + "; ".join(missing))


def test_a_missing_numba_internal_is_named(monkeypatch):
    from numba.core import caching

    monkeypatch.delattr(caching.CacheImpl, "_locator_classes")
    assert "jitcache: numba.core.caching.CacheImpl._locator_classes is missing" in \
        jitcache.missing_internals()
    monkeypatch.setattr(jitlink, "LINK_ONLY", None)
    monkeypatch.setattr(jitlink, "WHY", "AttributeError: numba's code library lacks finalize")
    assert jitlink.missing_internals() == [
        "jitlink: AttributeError: numba's code library lacks finalize"]


def test_only_the_entry_points_have_a_python_wrapper_and_a_cache():
    found = dict(dispatchers())
    assert ENTRIES <= {n.split(".")[1] for n in found}
    for name, d in found.items():
        entry = name.split(".")[1] in ENTRIES
        assert d.targetoptions.get("no_cpython_wrapper", False) is not entry, name
        if jitcache.CACHE:  # a usable cache folder: only the entry points write to it
            assert (type(d._cache).__name__ != "NullCache") is entry, name
        assert (d._compiler.pipeline_class is jitlink.LINK_ONLY) is not entry, name


def test_an_internal_function_compiles_to_ir_without_machine_code():
    cres = contact.sgn.get_compile_result(
        numba.core.typing.Signature(numba.float64, (numba.float64, numba.float64), None))
    lib = cres.library
    assert type(lib).__name__ == "IROnlyLibrary"
    assert lib._finalized
    # its IR is there to be linked, but no machine code was generated for it
    assert not lib._final_module.get_function(cres.fndesc.mangled_name).is_declaration
    assert not lib._codegen._engine.is_symbol_defined(cres.fndesc.mangled_name)
    assert cres.entry_point is not None  # (a null function numba never calls: see below)


def test_calling_an_internal_function_from_python_is_a_type_error_not_a_crash():
    # without the guard numba jumps to a null address: run it in a child process
    code = ("from gearpair.fast import contact\n"
            "try:\n    contact.sgn(1.0, 0.0)\n"
            "except TypeError as e:\n    print('TypeError', e)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    assert "TypeError sgn is an internal function of the fast engine" in res.stdout


@pytest.mark.parametrize("name", ["contact.evaluate", "rk.try_step", "loop.piece"])
def test_hot_functions_are_always_inlined(name):
    d = dict(dispatchers())[name]
    assert d.targetoptions.get("forceinline") is True


def test_compiled_code_neither_prints_nor_raises():
    # an internal function has no environment pointer (`jitlink`): what print() or a raise
    # with run-time values inside compiled code would read
    import ast

    for name, d in dispatchers():
        tree = ast.parse(inspect.getsource(d.py_func).lstrip())
        for node in ast.walk(tree):
            assert not isinstance(node, ast.Raise), name
            assert not (isinstance(node, ast.Call) and getattr(node.func, "id", "") == "print"), \
                name


def test_the_engine_imports_with_numba_jit_disabled():
    # NUMBA_DISABLE_JIT=1 (numba's debugging switch) leaves plain functions, which the
    # compiled-only guard must leave alone
    import os

    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    res = subprocess.run([sys.executable, "-c", "import gearpair.fast.loop as m; "
                          "print(type(m.piece).__name__)"], capture_output=True, text=True,
                         env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "function"


def test_the_engine_object_finds_the_numba_internals_it_uses():
    """`gearpair.aot` takes each entry point's LLVM module from numba's compile result;
    a numba without those internals is named here, not by a failing FMU build."""
    from gearpair import aot

    assert aot.missing_internals() == []
