"""How the fast engine's internal functions are compiled: to LLVM IR for their callers only.

numba compiles every jitted function into a code library of its own: it links in the
libraries of everything the function calls, optimizes the result and generates machine code
for it. For the engine's deep call tree (entry point -> advance loop -> piece -> scan ->
contact evaluation ...) that processes the same code once per level: a user's first
``gearpair simulate`` ran LLVM over 131,000 instructions to keep the 30,000 of its entry
point, and generated machine code for 40 libraries of which only one is ever called.

Only the engine's entry points are called from Python (`jitcache.jit_entry`). Every other
function is called from compiled code alone, so here it is compiled to LLVM IR and left
for its callers to link: its library links its own callees and stops there (no module
optimization, no machine code), and the entry point that finally links everything optimizes
and compiles the whole once. The arithmetic is the same IR through the same LLVM passes
without fast-math, so results are bit for bit those of the level-by-level build
(`tests/test_golden.py`). Such functions have no Python wrapper and cannot be cached on
their own (a cache holds machine code); the entry points, which contain them, are cached.
Nor do they get numba's environment pointer (what ``print`` or Python objects inside
compiled code would need): the engine's compiled code uses neither, and keeps it that way.

This leans on numba internals (`numba.core.codegen.JITCodeLibrary`, the compiler pipeline);
`LINK_ONLY` is None, and the engine compiles level by level as numba does by default, when
they are not as expected (`WHY` says why). That fallback is correct but slow to compile, so
`missing_internals` names what is missing and the test suite fails while it is active; the
numba versions pyproject.toml admits are the ones this was tested with.
"""

from __future__ import annotations

LINK_ONLY = None  # the compiler class for internal functions, or None: numba's default
WHY = ""


def _build():
    from numba.core import codegen, compiler
    from numba.core.compiler_lock import require_global_compiler_lock
    from numba.core.compiler_machinery import FunctionPass, register_pass
    from numba.core.typed_passes import NopythonTypeInference

    base = codegen.JITCodeLibrary
    missing = [n for n in ("_raise_if_finalized", "_get_module_for_linking",
                           "_ensure_finalized", "finalize") if not hasattr(base, n)]
    if missing:
        raise AttributeError("numba's code library lacks " + ", ".join(missing))

    class _NoEnv:
        """The codegen as seen by `get_executable` for an IR-only library: there is no
        machine code whose environment pointer could be set."""

        def __init__(self, cg):
            self._cg = cg

        def set_env(self, env_name, env):
            pass

        def __getattr__(self, name):
            return getattr(self._cg, name)

    class IROnlyLibrary(base):
        """A code library that links its callees' IR and is finalized without optimizing
        or generating machine code: its module is only ever linked into a caller's."""

        def finalize(self):
            require_global_compiler_lock()
            self._raise_if_finalized()
            seen = set()
            for lib in self._linking_libraries:
                if lib not in seen:
                    seen.add(lib)
                    self._reload_init.update(lib._reload_init)
                    self._final_module.link_in(lib._get_module_for_linking(), preserve=True)
            self._finalized = True

        def get_pointer_to_function(self, name):
            self._ensure_finalized()
            return 0  # no machine code: not callable from Python

        @property
        def codegen(self):
            return _NoEnv(self._codegen)

    @register_pass(mutates_CFG=False, analysis_only=False)
    class UseIROnlyLibrary(FunctionPass):
        """Give the function an `IROnlyLibrary` before it is lowered."""

        _name = "gearpair_ir_only_library"

        def __init__(self):
            FunctionPass.__init__(self)

        def run_pass(self, state):
            if state.library is None and _usable(state.targetctx.codegen()):
                state.library = IROnlyLibrary(state.targetctx.codegen(),
                                              state.func_id.func_qualname)
            return True

    probe: dict = {}

    def _usable(cg) -> bool:
        """Whether a library of this numba holds what `IROnlyLibrary.finalize` uses (else
        numba's own library is used: machine code at every level, as by default)."""
        global WHY
        if "ok" not in probe:
            lib = IROnlyLibrary(cg, "gearpair_probe")
            lacks = [n for n in ("_linking_libraries", "_final_module", "_reload_init")
                     if not hasattr(lib, n)]
            probe["ok"] = not lacks
            if lacks:
                WHY = "numba's code library instances lack " + ", ".join(lacks)
        return probe["ok"]

    class IROnlyCompiler(compiler.CompilerBase):
        """numba's nopython pipeline, lowering into an `IROnlyLibrary`."""

        def define_pipelines(self):
            pm = compiler.DefaultPassBuilder.define_nopython_pipeline(self.state)
            pm.add_pass_after(UseIROnlyLibrary, NopythonTypeInference)
            pm.finalize()
            return [pm]

    IROnlyCompiler.library_usable = staticmethod(_usable)
    return IROnlyCompiler


try:
    LINK_ONLY = _build()
except Exception as e:  # noqa: BLE001 - other numba internals: compile as numba does
    WHY = f"{type(e).__name__}: {e}"


def missing_internals() -> list[str]:
    """What of numba's internals this module needs and this numba lacks: [] when internal
    functions compile to LLVM IR only, else why numba's default compile is used instead."""
    if LINK_ONLY is None:
        return [f"jitlink: {WHY}"]
    from numba.core.registry import cpu_target

    if not LINK_ONLY.library_usable(cpu_target.target_context.codegen()):
        return [f"jitlink: {WHY}"]
    return []


def compiled_only(dispatcher):
    """Make a dispatcher without a Python wrapper refuse calls from Python (numba would
    jump to a null address) with a TypeError; compiled callers are unaffected."""
    from numba.core.dispatcher import Dispatcher

    if not isinstance(dispatcher, Dispatcher):  # NUMBA_DISABLE_JIT: the plain function
        return dispatcher
    cls = type(dispatcher)
    sub = _SUBCLASSES.get(cls)
    if sub is None:
        def __call__(self, *args, **kwargs):
            raise TypeError(f"{self.py_func.__qualname__} is an internal function of the fast "
                            "engine, called from its compiled code only; use FastEngine")

        sub = _SUBCLASSES[cls] = type("CompiledOnly" + cls.__name__, (cls,),
                                      {"__call__": __call__})
    dispatcher.__class__ = sub
    return dispatcher


_SUBCLASSES: dict = {}
