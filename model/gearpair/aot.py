"""The fast engine as one object file and a C header: the engine a C program links.

`write_engine` compiles four entry points of the fast engine, each ``int64_t f(int64_t
table_address)``, in a child process for a portable CPU (`shipped.portable_target`) and
writes them as one relocatable object with C names:

- ``gearpair_setup``: the model's records from the gear data and choices (`fast.setup`);
- ``gearpair_init``: the static equilibrium at the start time and its outputs (`fast.native`);
- ``gearpair_step``: one communication step (`fast.native`);
- ``gearpair_step_early``: the same step where it may return early at a contact event
  (FMI 3's early return; `fast.native`).

It is numba's own code, the same machine code the Python API runs for that CPU (one source,
the same bits), taken at the LLVM level: each entry point's module as numba optimized it,
a small wrapper per entry that calls numba's function with its calling convention (a return
slot and an exception slot: a status other than 0, which the engine never produces, returns
`FAILED`) and every other symbol made internal, so that numba's Python wrapper and its
C wrapper, which would need the Python C API and numba's helper library, are dropped as dead
code. What remains needs only ``fmod`` and ``memset`` from the C library (`LIBC`);
`undefined_symbols` checks an object.

The same linked module, emitted for `WIN64_TRIPLE` (``win64=True``), is the engine of the
FMU's Windows binary: LLVM's C calling convention is the target's (Win64 there), the data
layout the target's, and the COFF object needs the same two functions and, where a stack
frame exceeds 4 KB, LLVM's stack probe ``___chkstk_ms`` (`WIN64_LIBGCC`; mingw-w64 links
all three statically). numba compiles once for both (`build_objects`); the host's object keeps
its bytes.

The header (`engine_header`) is generated from the same declarations the compiled code
reads: the set-up table, the hand-off table and the shapes of its arrays for each number of
tracked tooth pairs, the step block's slots, the status codes and messages.

The numba internals used here (`INTERNALS`) are kept in this module; `missing_internals`
names any this numba lacks.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

#: (C name, module, entry point) of the engine's functions in the object.
ENTRIES = (("gearpair_setup", "fast.setup", "setup_entry"),
           ("gearpair_init", "fast.native", "init_entry"),
           ("gearpair_step", "fast.native", "step_entry"),
           ("gearpair_step_early", "fast.native", "step_early_entry"))
LIBC = ("fmod", "memset")  # what the object may need from outside
#: The Windows x86-64 target of the win64 object (mingw-w64's: COFF, the Win64 calling
#: convention), the CPU it is made for there and its file name.
WIN64_TRIPLE = "x86_64-w64-windows-gnu"
WIN64_CPU = "x86-64-v2"
WIN64_OBJECT = "gearpair_engine_win64.o"
#: what the win64 object may need besides `LIBC`: LLVM's stack probe for frames over 4 KB
#: on Windows, which mingw-w64's libgcc links statically into the DLL
WIN64_LIBGCC = ("___chkstk_ms",)
FAILED = -1  # what an entry returns when numba's function reports an exception
N_PAIRS_MAX = 8  # tracked tooth pairs the header has shapes for (contact ratio below 8)
INTERNALS = ("Dispatcher.overloads", "Dispatcher._cache", "numba.core.caching.NullCache",
             "CompileResult.library._final_module", "CompileResult.fndesc.mangled_name")

_WRAPPER = """
declare i32 @"{inner}"(ptr, ptr, i64)
define i64 @{name}(i64 %a) {{
  %ret = alloca i64
  %exc = alloca ptr
  store i64 0, ptr %ret
  store ptr null, ptr %exc
  %st = call i32 @"{inner}"(ptr %ret, ptr %exc, i64 %a)
  %ok = icmp eq i32 %st, 0
  %v = load i64, ptr %ret
  %r = select i1 %ok, i64 %v, i64 {failed}
  ret i64 %r
}}
"""


def _module_of(package: str, name: str, entry: str):
    """The LLVM module of one entry point, compiled now (numba's cache holds machine code,
    not the module) for int64, with the C wrapper `name` and every other symbol internal."""
    import importlib

    import llvmlite.binding as llvm
    from numba import types
    from numba.core.caching import NullCache

    disp = getattr(importlib.import_module(f"{package}.{name}"), entry)
    disp._cache = NullCache()  # compile: the module is wanted, not cached machine code
    sig = (types.int64,)
    disp.compile(sig)
    cres = disp.overloads[sig]
    mod = llvm.parse_bitcode(cres.library._final_module.as_bitcode())
    return cres.fndesc.mangled_name, mod


def _linked_module(package: str):
    """One LLVM module of `ENTRIES` with their C wrappers, every other symbol internal, for
    numba's target (the host's triple)."""
    import llvmlite.binding as llvm

    main = None
    for cname, module, entry in ENTRIES:
        inner, mod = _module_of(package, module, entry)
        wrapper = llvm.parse_assembly(_WRAPPER.format(inner=inner, name=cname, failed=FAILED))
        wrapper.triple, wrapper.data_layout = mod.triple, mod.data_layout
        mod.link_in(wrapper)
        for f in mod.functions:
            if not f.is_declaration and f.name != cname:
                f.linkage = "internal"
        for g in mod.global_variables:
            if not g.is_declaration:
                g.linkage = "internal"
        if main is None:
            main = mod
        else:
            main.link_in(mod)
    return main


def _emit(main, cpu: str, triple: str | None = None) -> bytes:
    """The object file of the linked module ``main`` (changed: dead code dropped) for
    ``triple`` (None: numba's, the host's). For another triple the module's data layout
    becomes the target's; the wrappers' and numba's functions, declared with LLVM's C
    calling convention, take the target's (Win64 for `WIN64_TRIPLE`)."""
    import llvmlite.binding as llvm

    if triple:
        main.triple = triple
    tm = llvm.Target.from_triple(main.triple).create_target_machine(
        cpu=cpu, features="", reloc="pic", codemodel="default", opt=3)
    if triple:
        main.data_layout = str(tm.target_data)
    pb = llvm.create_pass_builder(tm, llvm.create_pipeline_tuning_options(speed_level=0))
    mpm = llvm.create_new_module_pass_manager()
    mpm.add_global_dead_code_eliminate_pass()
    mpm.add_strip_dead_prototype_pass()
    mpm.run(main, pb)
    main.verify()
    return tm.emit_object(main)


def build_object(package: str, cpu: str, triple: str | None = None) -> bytes:
    """The object file of `ENTRIES` for ``triple`` (None: the host's; run in the process
    that compiles: see `write_engine`)."""
    import llvmlite.binding as llvm

    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    return _emit(_linked_module(package), cpu, triple)


def build_objects(package: str, cpu: str, triples) -> list[bytes]:
    """The object files of `ENTRIES` for each of ``triples`` (None: the host's), compiled
    by numba once: each is emitted from a copy of the one linked module (its bitcode read
    back), so the host's object has the same bytes as `build_object`'s."""
    import llvmlite.binding as llvm

    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    main = _linked_module(package)
    code = main.as_bitcode()
    return [_emit(llvm.parse_bitcode(code), cpu, t) for t in triples]


_CHILD = r"""
import json, sys
package, cpu, out, header, win64 = sys.argv[1:6]
import importlib
aot = importlib.import_module(package + ".aot")
made = {"ok": True}
if win64:
    objects = aot.build_objects(package, cpu, [None, aot.WIN64_TRIPLE])
else:
    objects = [aot.build_object(package, cpu)]
with open(out, "wb") as fh:
    fh.write(objects[0])
if win64:
    with open(win64, "wb") as fh:
        fh.write(objects[1])
with open(header, "w") as fh:
    fh.write(aot.engine_header(package))
print(json.dumps(made))
"""


def write_engine(folder: str | Path, package: str = "gearpair",
                 timeout: float = 1800.0, path: str | None = None,
                 win64: bool = False) -> dict:
    """Write ``gearpair_engine.o`` and ``gearpair_engine.h`` into ``folder``, compiled in a
    child process for the portable CPU (about 40 s), and with ``win64`` also
    ``gearpair_engine_win64.o``: the same module emitted for Windows x86-64 (`WIN64_TRIPLE`,
    a COFF object; only on an x86-64 host). Kept in the user cache under the engine's key,
    so a second build with unchanged engine sources copies them. ``path``: a folder the
    child imports ``package`` from first. Returns {"object", "header", "object_win64"
    (None without ``win64``), "cached"}."""
    import shutil

    from .shipped import portable_target, user_cache_dir

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cpu, _ = portable_target()
    if win64 and cpu != WIN64_CPU:
        raise RuntimeError(f"a win64 engine object is made on an x86-64 host only (here the "
                           f"portable CPU is {cpu})")
    key = _key(package)
    base = user_cache_dir()
    import hashlib

    own = hashlib.sha1(Path(__file__).read_bytes()).hexdigest()[:8]  # this file shapes it too
    keep = Path(base) / f"aot-{cpu}-{key}-{own}" if base and key else None
    obj, hdr = folder / "gearpair_engine.o", folder / "gearpair_engine.h"
    win = folder / WIN64_OBJECT if win64 else None
    wanted = [p for p in (obj, hdr, win) if p is not None]
    if keep is not None and all((keep / p.name).is_file() for p in wanted):
        for p in wanted:
            shutil.copyfile(keep / p.name, p)
        return {"object": str(obj), "header": str(hdr),
                "object_win64": str(win) if win else None, "cached": True}
    env = dict(os.environ, NUMBA_CPU_NAME=cpu, NUMBA_CPU_FEATURES="",
               GEARPAIR_COMPILE_NOTICE="")
    if path:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [path, env.get("PYTHONPATH")]))
    with tempfile.TemporaryDirectory(prefix="gearpair_aot_") as tmp:
        env["NUMBA_CACHE_DIR"] = tmp  # numba's cache of this child: thrown away
        proc = subprocess.run([sys.executable, "-c", _CHILD, package, cpu, str(obj),
                               str(hdr), str(win) if win else ""], env=env, cwd=tmp,
                              capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0 or not all(p.is_file() for p in wanted):
        raise RuntimeError(f"compiling the engine's object failed (exit {proc.returncode}): "
                           f"{(proc.stderr or proc.stdout)[-2000:]}")
    for p, allowed in ((obj, LIBC), (win, LIBC + WIN64_LIBGCC)):
        bad = sorted(set(undefined_symbols(p)) - set(allowed)) if p is not None else []
        if bad:
            raise RuntimeError(f"the engine's object {p.name} needs {', '.join(bad)} (only "
                               f"{', '.join(allowed)} allowed)")
    if keep is not None:
        try:
            keep.mkdir(parents=True, exist_ok=True)
            for p in wanted:
                shutil.copyfile(p, keep / p.name)
        except OSError:
            pass
    return {"object": str(obj), "header": str(hdr),
            "object_win64": str(win) if win else None, "cached": False}


def _key(package: str) -> str | None:
    """The engine's key (`jitcache.KEY`: the engine files' content) of ``package``, or
    None when it cannot be read (then nothing is reused)."""
    import importlib

    try:
        return importlib.import_module(package + ".jitcache").KEY
    except Exception:  # noqa: BLE001 - no key: no reuse
        return None


def undefined_symbols(path: str | Path) -> list[str]:
    """The symbols an object file needs from outside (its undefined global symbols): a
    64-bit ELF object or an x86-64 COFF object (`WIN64_OBJECT`)."""
    data = Path(path).read_bytes()
    import struct

    if data[:2] == b"\x64\x86":  # COFF, IMAGE_FILE_MACHINE_AMD64
        return _coff_undefined(data)
    if data[:4] != b"\x7fELF" or data[4] != 2:
        raise ValueError(f"{path} is not a 64-bit ELF or x86-64 COFF object")
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize)
                for i in range(shnum)]
    out = []
    for sh in sections:
        if sh[1] != 2:  # SHT_SYMTAB
            continue
        strtab = sections[sh[6]]
        for k in range(sh[5] // sh[9]):
            name_off, info, _, shndx, _, _ = struct.unpack_from("<IBBHQQ", data,
                                                                sh[4] + k * sh[9])
            if shndx == 0 and info >> 4 in (1, 2) and name_off:  # undefined global/weak
                end = data.index(b"\0", strtab[4] + name_off)
                out.append(data[strtab[4] + name_off:end].decode())
    return sorted(out)


def _coff_undefined(data: bytes) -> list[str]:
    """The undefined external symbols of a COFF object (PE/COFF specification, 5.4)."""
    import struct

    symtab, nsym = struct.unpack_from("<II", data, 8)
    strings = symtab + 18 * nsym
    out, k = [], 0
    while k < nsym:
        raw, value, section, _, storage, naux = struct.unpack_from("<8sIhHBB", data,
                                                                   symtab + 18 * k)
        if section == 0 and value == 0 and storage == 2:  # IMAGE_SYM_CLASS_EXTERNAL
            if raw[:4] == b"\0\0\0\0":  # a long name: offset into the string table
                off = strings + struct.unpack_from("<I", raw, 4)[0]
                name = data[off:data.index(b"\0", off)]
            else:
                name = raw.rstrip(b"\0")
            out.append(name.decode())
        k += 1 + naux
    return sorted(out)


def missing_internals() -> list[str]:
    """The numba internals `build_object` uses that this numba lacks ([] when all are
    there)."""
    from numba.core import caching, compiler

    from .fast.native import step_entry

    out = []
    if not hasattr(caching, "NullCache"):
        out.append("aot: numba.core.caching.NullCache is missing")
    for attr in ("overloads", "_cache"):
        if not hasattr(step_entry, attr):
            out.append(f"aot: numba's Dispatcher.{attr} is missing")
    if "library" not in getattr(compiler.CompileResult, "_fields", ("library",)):
        out.append("aot: numba's CompileResult.library is missing")
    return out


def engine_header(package: str = "gearpair") -> str:
    """The C header of the engine's object: its functions and the layouts they read, from
    the declarations the compiled code reads (`fast.setup`, `fast.native`, `fast.engine`,
    `stepblock`)."""
    import importlib

    setup = importlib.import_module(package + ".fast.setup")
    native = importlib.import_module(package + ".fast.native")
    engine = importlib.import_module(package + ".fast.engine")
    layout = importlib.import_module(package + ".fast.layout")
    sb = importlib.import_module(package + ".stepblock")
    out = ["/* The fast engine of gearpair as a C program links it (gearpair_engine.o).",
           " * Generated by gearpair.aot.engine_header: do not edit. */",
           "#ifndef GEARPAIR_ENGINE_H", "#define GEARPAIR_ENGINE_H", "#include <stdint.h>", ""]
    for cname, _, entry in ENTRIES:
        out.append(f"int64_t {cname}(int64_t table_address); /* {entry} */")
    out += [f"#define GP_FAILED ({FAILED})", ""]

    def enum(prefix, names):
        return "enum { " + ", ".join(f"{prefix}{n.upper()} = {i}" for i, n in enumerate(names)) \
            + " };"

    def ints(name, values):
        return f"static const int64_t {name}[{len(values)}] = {{" + \
            ", ".join(str(int(v)) for v in values) + "};"

    def names(name, values):
        return f"static const char *const {name}[{len(values)}] = {{" + \
            ", ".join(f'"{v}"' for v in values) + "};"

    arrays = setup.SETUP_ARRAYS
    out += ["/* the set-up table: address and length of each array (length 0: the caller's) */",
            f"#define GP_SETUP_WORDS {setup.N_SETUP_TABLE}",
            enum("GPS_", [a[0] for a in arrays]),
            ints("GP_SETUP_LEN", [a[2] or 0 for a in arrays]),
            f'#define GP_SETUP_KINDS "{"".join(a[1] for a in arrays)}"',
            f"#define GP_N_GEAR {setup.N_GP}", names("GP_GEAR_NAMES", setup.GP_NAMES),
            f"#define GP_N_CHOICE {setup.N_C}",
            enum("GPC_", ["law", "scale", "sep", "fric", "veps", "slide", "tie", "back", "tors",
                          "mus", "vs", "rtol", "atol", "maxstep", "nsamp", "spacing", "ttol",
                          "maxev", "lti", "method", "tabmean"]),
            names("GP_SETUP_STATUS", ["ok", "interference", "contact ratio below 1",
                                      "no spline", "no modes", "not a uniform grid",
                                      "table size"]), ""]
    out += ["/* ModelData.flag slots the caller reads */",
            *(f"#define GP_{n} {getattr(layout, n)}" for n in
              ("I_NP", "I_KIND", "I_NTAB", "I_LTI", "I_MAXEV", "KIND_CUBIC", "N_MP", "N_MI",
               "N_Y")), ""]
    out += _messages(setup, layout, importlib.import_module(package + ".engine"))
    kinds = native.KINDS
    shapes = []
    for n in range(1, N_PAIRS_MAX + 1):
        wk = engine.work_buffers(n)
        _, hs = engine.state_buffer(n)
        rows = [list(a.shape) + [0] * (3 - a.ndim) for a in wk]
        shapes.append(rows)
    _, hs1 = engine.state_buffer(1)
    _, hs2 = engine.state_buffer(2)
    base1 = [a.__array_interface__["data"][0] for a in hs1]
    base2 = [a.__array_interface__["data"][0] for a in hs2]
    off1 = [(b - base1[0]) // 8 for b in base1]
    off2 = [(b - base2[0]) // 8 for b in base2]
    len1, len2 = [a.shape[0] for a in hs1], [a.shape[0] for a in hs2]
    out += [f"#define GP_WORK_SUMMARY {layout.Work._fields.index('summary')}",
            f"#define GP_CLOCK {layout.HybridState._fields.index('clock')}", ""]
    out += ["/* the hand-off table: 4 words per array (address, dimensions), in this order:",
            " * ModelData (6), Work (18), HybridState (6: views of the state buffer), the step",
            " * block, the state buffer, its rollback copy, then from GP_HANDOFF_RUN on the",
            " * arrays of a recorded run (the Python API's; zero words, empty, for a step);",
            " * kinds f/i (float64/int64) and ndim */",
            f"#define GP_HANDOFF_WORDS {native.N_TABLE}",
            f"#define GP_HANDOFF_ARRAYS {len(kinds)}",
            f"#define GP_HANDOFF_RUN {native.K_GRID}",
            names("GP_HANDOFF_KIND", kinds),
            f"#define GP_N_PAIRS_MAX {N_PAIRS_MAX}",
            "/* Work's shapes for n tracked pairs: GP_WORK_SHAPE[n - 1][array][dim] */",
            f"static const int64_t GP_WORK_SHAPE[{N_PAIRS_MAX}][{len(shapes[0])}][3] = {{"]
    for rows in shapes:
        out.append("    {" + ", ".join("{" + ", ".join(map(str, r)) + "}" for r in rows) + "},")
    out += ["};",
            "/* HybridState in the state buffer: offset and length a + b n (words) */",
            ints("GP_STATE_OFF_A", [2 * a - b for a, b in zip(off1, off2, strict=True)]),
            ints("GP_STATE_OFF_B", [b - a for a, b in zip(off1, off2, strict=True)]),
            ints("GP_STATE_LEN_A", [2 * a - b for a, b in zip(len1, len2, strict=True)]),
            ints("GP_STATE_LEN_B", [b - a for a, b in zip(len1, len2, strict=True)]),
            f"#define GP_STATE_WORDS(n) ({2 * (off1[-1] + len1[-1]) - (off2[-1] + len2[-1])}"
            f" + {(off2[-1] + len2[-1]) - (off1[-1] + len1[-1])} * (n))", ""]
    xs = ("X_TEND", "X_TCHK", "X_H", "X_TORQUE", "X_SPEED", "X_LOAD", "X_LOADON", "X_FMU",
          "X_BAD", "X_REC", "N_X", "STEP_DONE", "STEP_REFUSED", "STEP_FAILED",
          "STEP_NONFINITE")
    out += ["/* the step block and what a step returns */",
            *(f"#define GP_{n} {getattr(sb, n)}" for n in xs),
            f"#define GP_N_RECORD {len(sb.STEP_RECORD)}",
            names("GP_RECORD_NAMES", sb.STEP_RECORD), "", "#endif", ""]
    return "\n".join(out)


def _c_format(text: str, fields: dict[str, str]) -> str:
    """A C string literal of the message ``text`` with each rendered value (``fields``'s
    keys, in the order they appear) replaced by its printf conversion; '%' escaped."""
    out = text.replace("%", "%%")
    for shown, conversion in fields.items():
        if out.count(shown) != 1:
            raise RuntimeError(f"cannot make a C format of {text!r}: {shown!r} is not there once")
        out = out.replace(shown, conversion)
    return '"' + out.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _messages(setup, layout, engine) -> list[str]:
    """What the engine's statuses mean, as the Python API says it (`setup.setup_message`,
    `engine.run_failure_message`), as printf formats for a C caller: the set-up's by status
    (one %.3f: the contact ratio), a run failure's (%.9g time, %s flank state, %.6g DTE and,
    when unbounded, %.4g bound)."""
    import numpy as np

    geo = np.zeros(setup.N_GEO)
    geo[setup.GEO_EPS] = 0.123  # rendered "0.123" by the .3f of the contact-ratio message
    texts = [_c_format(setup.setup_message(k, geo), {"0.123": "%.3f"} if
                       k == setup.SETUP_CONTACT_RATIO else {}) for k in range(7)]
    marks = {"1.23456789e-300": "%.9g", engine.FLANK_STATE[0]: "%s", "2.34567e-300": "%.6g",
             "3.456e-300": "%.4g"}
    missed = engine.run_failure_message("missed", 1.23456789e-300, 0, 2.34567e-300, 0.0)
    unbounded = engine.run_failure_message("unbounded", 1.23456789e-300, 0, 2.34567e-300,
                                           3.456e-300)
    flank = ", ".join(f'"{s}"' for s in engine.FLANK_STATE)
    return ["/* what a status means, as printf formats (Python's words) */",
            f"#define GP_GEO_EPS {setup.GEO_EPS}",
            f"static const char *const GP_SETUP_TEXT[{len(texts)}] = {{" + ", ".join(texts)
            + "};",
            f"static const char *const GP_FLANK_STATE[{len(engine.FLANK_STATE)}] = {{{flank}}};",
            "#define GP_FAIL_MISSED " + _c_format(missed, {k: v for k, v in marks.items()
                                                          if k != "3.456e-300"}),
            "#define GP_FAIL_UNBOUNDED " + _c_format(unbounded, marks),
            *(f"#define GP_{n} {getattr(layout, n)}" for n in
              ("O_STATUS", "O_TFAIL", "O_DFAIL", "O_CFAIL", "O_BFAIL", "STATUS_OK",
               "STATUS_EVENTS", "STATUS_STEP", "STATUS_MISSED", "STATUS_UNBOUNDED", "T_T")),
            ""]
