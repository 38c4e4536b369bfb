"""Build the GearPair FMI 2.0 co-simulation FMU: ``python build_fmu.py [--out dist]``.

Runs the pythonfmu builder on ``fmu_src/GearPair.py`` with a copy of ``model/gearpair`` and a
``requirements.txt`` as project files (so the FMU's resources hold ``gearpair/``), then
completes the modelDescription.xml that pythonfmu 0.7.0 leaves partial: unit definitions,
units/display units/min/max, ModelStructure dependencies and InitialUnknowns, capability
flags. It also generates ``documentation/index.html``. Every variable's data comes from
``GearPair.interface()``, which reads ``GearParams.describe()``.

The FMU's binary ``binaries/linux64/GearPair.so`` is this project's C layer (``fmu_src/c``:
the generic FMI layer, GearPair's model part, the Python slave's loader), compiled here with
the system C compiler and headers generated from the final modelDescription.xml
(``fmu_src/fmu_config.py``), linked with the fast engine's object file, which numba compiles
from the same sources as the Python API (`gearpair.aot`): the default engine needs no
Python. pythonfmu's library ships beside it as ``GearPair_pythonfmu.so`` and runs the Python
slave for the scipy reference engine only.

``binaries/win64/GearPair.dll`` is the same C layer cross-compiled with mingw-w64
(``x86_64-w64-mingw32-gcc``), linked with the engine's object emitted for Windows x86-64
from the same numba module; it loads no Python (``fmu_src/c/no_python.c``: engine = 1 is
refused with a clear error) and needs only KERNEL32.dll and msvcrt.dll. Without mingw-w64
(or with ``--no-win64``) the FMU holds ``binaries/linux64`` only and the build says so.
pythonfmu's own win64 binary is left out (see docs/hosts.md).

``GearPair3.fmu`` beside it is the same FMU for FMI 3.0 co-simulation (`build_fmi3`): its
modelDescription generated from GearPair.fmu's (`fmi3_model_description`: the same
variables and value references, Float64/Int32/Boolean, the integer-coded choices as
Enumerations; Event Mode and early return declared), its binaries the generic FMI 3 layer
``fmu_src/c/fmi3Functions.c`` over the same model part and engine object, for the same
platforms (``x86_64-linux``, ``x86_64-windows``); the FMI 3 headers come from fmpy.
"""

from __future__ import annotations

import argparse
import html
import importlib
import importlib.util
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
SCRIPT = ROOT / "fmu_src" / "GearPair.py"
PACKAGE = ROOT / "model" / "gearpair"
SHIM_SRC = ROOT / "fmu_src" / "c"
PYTHON_SCRIPT = ROOT / "fmu_src" / "gearpair_python.py"  # resources: which Python to load
INNER_SUFFIX = "_pythonfmu.so"  # pythonfmu's library beside the C layer: <model><suffix>
# the slave's own modules beside it (fmu_src; resources in the FMU)
SLAVE_MODULES = ("fmu_interface", "fmu_bundle", "fmu_state")


def requirements() -> str:
    """The FMU's ``resources/requirements.txt``: pyproject.toml's run-time dependencies, with
    their bounds (the versions the bundled package was tested with)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    return "".join(d + "\n" for d in deps)

# Units: name -> SI base-unit exponents (FMI 2.0 BaseUnit attributes).
UNITS: dict[str, dict[str, int]] = {
    "1": {},
    "s": {"s": 1},
    "m": {"m": 1},
    "kg": {"kg": 1},
    "kg.m2": {"kg": 1, "m": 2},
    "rad": {"rad": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N.m": {"kg": 1, "m": 2, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "Pa": {"kg": 1, "m": -1, "s": -2},
    "rad/s": {"rad": 1, "s": -1},
    "m/s": {"m": 1, "s": -1},
}
# Display units: value_display = factor * value + offset.
DISPLAY_UNITS: dict[str, tuple[tuple[str, float], ...]] = {
    "rad/s": (("rpm", 60.0 / (2.0 * math.pi)),),
    "m": (("um", 1e6), ("mm", 1e3)),
    "N": (("kN", 1e-3),),
    "rad": (("deg", 180.0 / math.pi),),
}
CAPABILITIES = {
    "canHandleVariableCommunicationStepSize": "true",
    "canGetAndSetFMUstate": "true",
    "canSerializeFMUstate": "true",
    "canInterpolateInputs": "false",
    "needsExecutionTool": "false",  # the fast engine is compiled into the binary
}
DEFAULT_EXPERIMENT = {"startTime": "0", "stopTime": "0.5", "stepSize": "0.0001"}
# Schema order of fmiModelDescription's children.
_ORDER = ("ModelExchange", "CoSimulation", "UnitDefinitions", "TypeDefinitions",
          "LogCategories", "DefaultExperiment", "VendorAnnotations", "ModelVariables",
          "ModelStructure")


def _num(x: float | int) -> str:
    """Shortest text that reads back to the same double (or integer)."""
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return str(x)
    return repr(float(x))


# -- modelDescription.xml ---------------------------------------------------------------------
def complete_model_description(xml: bytes, spec: list[dict]) -> bytes:
    """Return modelDescription.xml completed from the interface spec."""
    root = ET.fromstring(xml)
    by_name = {v["name"]: v for v in spec}

    cosim = root.find("CoSimulation")
    if cosim is None:
        raise RuntimeError("modelDescription.xml has no CoSimulation element")
    for k, v in CAPABILITIES.items():
        cosim.set(k, v)

    for tag in ("UnitDefinitions", "TypeDefinitions", "DefaultExperiment"):
        for el in root.findall(tag):
            root.remove(el)

    used = {v["unit"] for v in spec if v["unit"]}
    unknown = used - UNITS.keys()
    if unknown:
        raise RuntimeError(f"no unit definition for {sorted(unknown)}; add them to UNITS")
    units = ET.Element("UnitDefinitions")
    for name in sorted(used):
        u = ET.SubElement(units, "Unit", name=name)
        ET.SubElement(u, "BaseUnit", {k: str(e) for k, e in UNITS[name].items()})
        for dname, factor in DISPLAY_UNITS.get(name, ()):
            ET.SubElement(u, "DisplayUnit", name=dname, factor=repr(factor))
    root.append(units)
    root.append(ET.Element("DefaultExperiment", DEFAULT_EXPERIMENT))

    variables = root.find("ModelVariables")
    index: dict[str, int] = {}
    for i, sv in enumerate(variables.findall("ScalarVariable"), start=1):
        name = sv.get("name")
        v = by_name.get(name)
        if v is None:
            raise RuntimeError(f"variable {name} is not in the interface spec")
        index[name] = i
        sv.set("description", v["description"])
        if sv.get("causality") != v["causality"] or sv.get("variability") != v["variability"]:
            raise RuntimeError(f"{name}: causality/variability differ from the spec")
        typed = sv.find(v["type"])
        if typed is None:
            raise RuntimeError(f"{name}: expected a {v['type']} element")
        if v["type"] == "Real":
            if v["unit"]:
                typed.set("unit", v["unit"])
            if v["display_unit"]:
                if v["display_unit"] not in dict(DISPLAY_UNITS.get(v["unit"], ())):
                    raise RuntimeError(f"{name}: display unit {v['display_unit']} not defined")
                typed.set("displayUnit", v["display_unit"])
        for key in ("min", "max"):
            if v[key] is not None and v["type"] != "Boolean":
                typed.set(key, _num(int(v[key]) if v["type"] == "Integer" else float(v[key])))
        if v["start"] is not None:
            typed.set("start", _num(v["start"]))
        elif "start" in typed.attrib:
            del typed.attrib["start"]
    missing = set(by_name) - set(index)
    if missing:
        raise RuntimeError(f"variables missing from modelDescription.xml: {sorted(missing)}")

    # initial outputs (fmi2ExitInitializationMode: the static equilibrium) follow from the
    # torque and speed inputs and the parameters, not from load_speed, which acts only
    # through steps: declaring all inputs made OMSimulator report an algebraic loop at
    # initialization wherever load_speed is fed back
    at_init = [str(index[v["name"]]) for v in spec
               if v["causality"] == "parameter" or v["name"] in ("torque", "speed")]
    for el in root.findall("ModelStructure"):
        root.remove(el)
    structure = ET.Element("ModelStructure")
    outs = ET.SubElement(structure, "Outputs")
    init = ET.SubElement(structure, "InitialUnknowns")
    for v in spec:
        if v["causality"] != "output":
            continue
        i = str(index[v["name"]])
        # outputs change only in fmi2DoStep: no direct dependency on an input at a
        # communication point (a master sorting by them would see false algebraic loops)
        ET.SubElement(outs, "Unknown", index=i, dependencies="", dependenciesKind="")
        if v["name"] == "n_events":  # 0 before the first step: depends on nothing
            ET.SubElement(init, "Unknown", index=i, dependencies="", dependenciesKind="")
        else:
            ET.SubElement(init, "Unknown", index=i, dependencies=" ".join(at_init),
                          dependenciesKind=" ".join(["dependent"] * len(at_init)))
    root.append(structure)

    root[:] = sorted(root, key=lambda el: _ORDER.index(el.tag))  # stable: keeps inner order
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _rewrite_zip(fmu: Path, replace: dict[str, bytes], drop=lambda name: False) -> None:
    """Rewrite the FMU with some members replaced or added (``replace``) and others left
    out (``drop(name)`` true)."""
    tmp = fmu.with_suffix(".tmp")
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            if drop(item.filename):
                continue
            data = replace.pop(item.filename, None)
            zout.writestr(item.filename, zin.read(item) if data is None else data,
                          compress_type=zipfile.ZIP_DEFLATED)
        for name, data in replace.items():
            zout.writestr(name, data, compress_type=zipfile.ZIP_DEFLATED)
    tmp.replace(fmu)


# -- the C layer ----------------------------------------------------------------------------
def add_c_layer(fmu: Path, spec: list[dict] | None = None, gp=None,
                progress=lambda msg: None, win64: bool | None = None) -> list[str]:
    """Make the FMU's Linux binary this project's C layer (fmu_src/c): for GearPair (``spec``
    its `GearPair.interface`, ``gp`` the bundled package) the generic FMI layer with
    GearPair's model part, linked with the fast engine's object file (`gearpair.aot`); for
    another pythonfmu FMU (no ``gp``) the generic layer over its Python slave. pythonfmu's
    library moves beside it as ``<modelIdentifier>_pythonfmu.so`` (GearPair: for the
    reference engine, which alone needs Python). For GearPair also the win64 binary
    (`compile_win64_layer`) when ``win64`` (None: when `win64_compiler` finds mingw-w64).
    Other binaries (pythonfmu's) are left out. The resources get ``python.txt`` (this
    interpreter, which the C layer loads in hosts that are not Python) and
    ``gearpair_python.py``. Call it on the FMU with its final modelDescription.xml. Returns
    the platforms the FMU holds binaries for."""
    with zipfile.ZipFile(fmu) as z:
        xml = z.read("modelDescription.xml")
        model = ET.fromstring(xml).find("CoSimulation").get("modelIdentifier")
        pythonfmu_lib = z.read(f"binaries/linux64/{model}.so")
    win_cc = None
    if gp is not None and win64 is not False:
        win_cc = win64_compiler()
        if win_cc is None and win64:
            raise RuntimeError(f"a win64 binary needs mingw-w64: {WIN64_MISSING}")
    replace = {f"resources/{PYTHON_SCRIPT.name}": PYTHON_SCRIPT.read_bytes(),
               "resources/python.txt": _describe_python().encode()}
    with tempfile.TemporaryDirectory(prefix="gearpair_c_") as tmp:
        lib = compile_c_layer(xml, spec, gp, Path(tmp), model, progress,
                              win64=win_cc is not None)
        replace[f"binaries/linux64/{model}.so"] = lib
        replace[f"binaries/linux64/{model}{INNER_SUFFIX}"] = pythonfmu_lib
        if win_cc is not None:
            progress(f"cross-compiling the FMU's win64 binary ({Path(win_cc).name})")
            replace[f"binaries/win64/{model}.dll"] = compile_win64_layer(Path(tmp), model,
                                                                         win_cc)
        elif gp is not None and win64 is None:
            progress(f"no win64 binary: {WIN64_MISSING}; GearPair.fmu holds binaries/linux64 "
                     "only")
    _rewrite_zip(fmu, replace, drop=lambda name: name.startswith("binaries/")
                 and not name.startswith("binaries/linux64/"))
    return ["linux64"] + (["win64"] if win_cc is not None else [])


def c_compiler() -> str:
    """The C compiler for the FMU's binary ($CC, else gcc or cc); raises with what to
    install."""
    for cand in (os.environ.get("CC"), "gcc", "cc"):
        if cand and shutil.which(cand):
            return shutil.which(cand)
    raise RuntimeError("building GearPair.fmu needs a C compiler for its binary "
                       "(fmu_src/c): install gcc (Debian/Ubuntu: apt-get install gcc) or set CC")


# what the generic FMI layers of both versions share: logging, values, FMU states (fmu_layer.h)
FMU_LAYER = ("fmu_log.c", "fmu_values.c", "fmu_states.c")
FMI2_LAYER = ("fmi2Functions.c", "fmi2States.c", *FMU_LAYER)  # the generic FMI 2 layer
C_SOURCES = (*FMI2_LAYER, "gearpair_fmu.c", "gearpair_model.c", "python_slave.c")
# the win64 binary: the same layer with the stand-in that loads no Python (engine = 1 refused)
WIN64_SOURCES = (*FMI2_LAYER, "gearpair_fmu.c", "gearpair_model.c", "no_python.c")
WIN64_CC = "x86_64-w64-mingw32-gcc"
WIN64_MISSING = (f"no mingw-w64 cross compiler ({WIN64_CC}; Debian/Ubuntu: apt-get install "
                 "gcc-mingw-w64-x86-64)")
# the DLLs the win64 binary may import: Windows' own (the C runtime msvcrt, or the UCRT)
WIN64_SYSTEM_DLLS = ("kernel32.dll", "msvcrt.dll", "ucrtbase.dll")
PYTHON_SOURCES = (*FMI2_LAYER, "python_fmu.c", "python_slave.c")  # another slave
NOOP_SOURCES = (*FMI2_LAYER, "noop_fmu.c")  # the bench's floor: a model doing nothing


def noop_binary(xml: bytes, workdir: Path) -> bytes:
    """The binary of an FMU with the variables of ``xml`` whose model does nothing: the
    generic FMI layer alone (`gearpair.bench` measures its cost per call with it)."""
    return compile_c_layer(xml, None, None, workdir, sources=NOOP_SOURCES)


def compile_c_layer(xml: bytes, spec: list[dict] | None, gp, workdir: Path,
                    model: str = "GearPair", progress=lambda msg: None,
                    sources: tuple[str, ...] = PYTHON_SOURCES, win64: bool = False) -> bytes:
    """The FMU's binary: the generic FMI layer, GearPair's model part and the Python slave
    (fmu_src/c) with the generated headers (`fmu_config`), linked with the engine's object
    (`gearpair.aot.write_engine`, for a portable CPU; cached by the engine's sources). With
    ``win64`` the engine's object for Windows is written into ``workdir`` too, for
    `compile_win64_layer`, which uses the headers left there.

    ``-z nodelete``: a host's dlclose must not unload the code an interpreter started for the
    reference engine, which lives on, still calls into (the slave's logger)."""
    fmu_config = _fmu_config()
    (workdir / "config.h").write_text(fmu_config.config_h(xml, spec, model + INNER_SUFFIX))
    objects = []
    if gp is not None:
        aot = importlib.import_module(gp.__name__ + ".aot")
        shipped = importlib.import_module(gp.__name__ + ".shipped")
        # the one slow step of a build: say what it is before a silence of half a minute
        progress(f"compiling the fast engine into the FMU's binary, for "
                 f"{shipped.portable_target()[0]} CPUs: about 40 s the first time, a moment "
                 "when the user cache holds it for the engine's sources")
        t0 = time.perf_counter()
        made = aot.write_engine(workdir, path=str(PACKAGE.parent), win64=win64)
        progress(f"the engine's object {'from the cache' if made['cached'] else 'compiled'} "
                 f"in {time.perf_counter() - t0:.0f} s")
        (workdir / "gearpair_config.h").write_text(fmu_config.gearpair_config_h(spec, gp))
        sources, objects = C_SOURCES, [made["object"]]
    lib = workdir / f"{model}.so"
    cmd = [c_compiler(), "-O2", "-std=c11", "-shared", "-fPIC", "-fvisibility=hidden",
           "-Wall", "-Wextra", "-Werror", f"-I{workdir}", f"-I{SHIM_SRC}", "-o", str(lib),
           *(str(SHIM_SRC / f) for f in sources), *objects,
           "-Wl,-z,nodelete", "-Wl,--no-undefined", "-ldl", "-lm", "-lpthread"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"compiling the FMU's C layer failed:\n{' '.join(cmd)}\n{r.stderr}")
    return lib.read_bytes()


def win64_compiler() -> str | None:
    """The mingw-w64 C compiler for the FMU's win64 binary ($GEARPAIR_WIN64_CC, else
    x86_64-w64-mingw32-gcc on PATH), or None: none there, the host is not x86-64 (the
    engine's object for Windows is emitted from an x86-64 module), or $GEARPAIR_WIN64_CC
    is set empty (no win64 binary)."""
    import platform

    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    cand = os.environ.get("GEARPAIR_WIN64_CC", WIN64_CC)
    return shutil.which(cand) if cand else None


def compile_win64_layer(workdir: Path, model: str = "GearPair",
                        cc: str | None = None) -> bytes:
    """The FMU's win64 binary: the C layer of `WIN64_SOURCES` cross-compiled with mingw-w64
    (``cc``, default `win64_compiler`) with the headers `compile_c_layer` wrote into
    ``workdir`` and linked with the engine's object for Windows there. C99 printf
    (``__USE_MINGW_ANSI_STDIO``: messages as on Linux), libgcc linked in, no timestamp, no
    symbol table (``-s``). Checked: it imports only `WIN64_SYSTEM_DLLS`."""
    aot_obj = workdir / "gearpair_engine_win64.o"
    cc = cc or win64_compiler()
    if cc is None:
        raise RuntimeError(WIN64_MISSING)
    dll = workdir / f"{model}.dll"
    cmd = [cc, "-O2", "-std=c11", "-shared", "-Wall", "-Wextra", "-Werror",
           "-D__USE_MINGW_ANSI_STDIO=1", f"-I{workdir}", f"-I{SHIM_SRC}", "-o", str(dll),
           *(str(SHIM_SRC / f) for f in WIN64_SOURCES), str(aot_obj),
           "-static-libgcc", "-Wl,--no-undefined", "-Wl,--no-insert-timestamp", "-s"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"compiling the FMU's win64 binary failed:\n{' '.join(cmd)}\n"
                           f"{r.stderr}")
    data = dll.read_bytes()
    other = [d for d in pe_imports(data) if d.lower() not in WIN64_SYSTEM_DLLS]
    if other:
        raise RuntimeError(f"the FMU's win64 binary imports {', '.join(other)}; only "
                           f"{', '.join(WIN64_SYSTEM_DLLS)} may be needed")
    return data


def pe_imports(data: bytes) -> list[str]:
    """The DLLs a PE32+ image (a win64 DLL) imports, from its import directory."""
    import struct

    pe, = struct.unpack_from("<I", data, 0x3C)
    if data[pe:pe + 4] != b"PE\0\0":
        raise ValueError("not a PE image")
    nsec, = struct.unpack_from("<H", data, pe + 6)
    opt_size, = struct.unpack_from("<H", data, pe + 20)
    opt = pe + 24
    if struct.unpack_from("<H", data, opt)[0] != 0x20B:
        raise ValueError("not a PE32+ (64-bit) image")
    rva, _ = struct.unpack_from("<II", data, opt + 112 + 8)  # data directory 1: imports
    sections = [struct.unpack_from("<IIII", data, opt + opt_size + 40 * k + 8)
                for k in range(nsec)]  # virtual size, address, raw size, raw pointer

    def at(r):
        for vsize, vaddr, _, raw in sections:
            if vaddr <= r < vaddr + vsize:
                return raw + r - vaddr
        raise ValueError(f"RVA {r:#x} is in no section")

    out, k = [], at(rva) if rva else None
    while k is not None:
        name_rva, = struct.unpack_from("<I", data, k + 12)
        if not name_rva:
            break
        off = at(name_rva)
        out.append(data[off:data.index(b"\0", off)].decode())
        k += 20
    return out


def _fmu_config():
    spec = importlib.util.spec_from_file_location("_gearpair_fmu_config",
                                                  SCRIPT.parent / "fmu_config.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# -- the FMI 3.0 FMU: GearPair3.fmu -----------------------------------------------------------
FMI3_MODEL = "GearPair3"
# the generic FMI 3 layer over the same model part; the win64 binary loads no Python
FMI3_LAYER = ("fmi3Functions.c", "fmi3_states.c", "fmi3_none.c", *FMU_LAYER)
FMI3_SOURCES = (*FMI3_LAYER, "gearpair_fmu.c", "gearpair_model.c", "python_slave.c")
FMI3_WIN64_SOURCES = (*FMI3_LAYER, "gearpair_fmu.c", "gearpair_model.c", "no_python.c")
FMI3_PLATFORM = {"linux64": ("x86_64-linux", ".so"), "win64": ("x86_64-windows", ".dll")}
FMI3_CAPABILITIES = {
    "needsExecutionTool": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
    "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
    "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
    "providesPerElementDependencies": "false",
    "canHandleVariableCommunicationStepSize": "true", "maxOutputDerivativeOrder": "0",
    "providesIntermediateUpdate": "false", "canReturnEarlyAfterIntermediateUpdate": "false",
    "mightReturnEarlyFromDoStep": "true", "hasEventMode": "true",
    "providesEvaluateDiscreteStates": "false"}
_FMI3_ROOT = ("modelName", "description", "author", "version", "copyright", "license",
              "generationTool", "generationDateAndTime", "variableNamingConvention")


def fmi3_type_name(name: str) -> str:
    """The EnumerationType of an integer-coded parameter: friction_law -> FrictionLaw."""
    return "".join(w.capitalize() for w in name.split("_"))


def fmi3_model_description(xml: bytes, spec: list[dict],
                           model: str = FMI3_MODEL) -> tuple[bytes, int]:
    """GearPair3.fmu's modelDescription.xml (FMI 3.0) and the value reference of its
    independent variable ``time``, from GearPair.fmu's final one (FMI 2.0, `
    complete_model_description`) and the interface ``spec``: the same variables, value
    references, units, ranges and start values, typed Float64, Int32 and Boolean, and every
    integer-coded choice (``spec``'s codes) an Enumeration of its own type; ``time`` (FMI 3
    requires one independent variable) takes the value reference after the last one; the
    instantiation token is GearPair.fmu's GUID. The fmi3 layer types the variables by the
    same rule (fmi3Functions.c, `kind_of`)."""
    src = ET.fromstring(xml)
    by_name = {v["name"]: v for v in spec}
    root = ET.Element("fmiModelDescription", {"fmiVersion": "3.0"})
    for key in _FMI3_ROOT:
        if src.get(key):
            root.set(key, src.get(key))
    root.set("instantiationToken", src.get("guid"))
    ET.SubElement(root, "CoSimulation", {"modelIdentifier": model, **FMI3_CAPABILITIES})
    root.append(src.find("UnitDefinitions"))
    types = ET.SubElement(root, "TypeDefinitions")
    for v in spec:
        if v["codes"]:
            t = ET.SubElement(types, "EnumerationType", name=fmi3_type_name(v["name"]))
            for i, code in enumerate(v["codes"]):
                ET.SubElement(t, "Item", name=code, value=str(i))
    logs = src.find("LogCategories")
    for cat in logs if logs is not None else ():
        cat.set("description", cat.get("description", "").replace("fmi2", "fmi3"))
    if logs is not None:
        root.append(logs)
    root.append(src.find("DefaultExperiment"))

    svs = src.find("ModelVariables").findall("ScalarVariable")
    vrs = [int(sv.get("valueReference")) for sv in svs]
    time_vr = max(vrs) + 1
    variables = ET.SubElement(root, "ModelVariables")
    ET.SubElement(variables, "Float64", name="time", valueReference=str(time_vr),
                  causality="independent", variability="continuous",
                  description="simulation time")
    for sv in svs:
        typed, v = sv[0], by_name[sv.get("name")]
        tag = {"Real": "Float64", "Boolean": "Boolean"}.get(typed.tag) or \
            ("Enumeration" if v["codes"] else "Int32")
        el = ET.SubElement(variables, tag, {k: sv.get(k) for k in (
            "name", "valueReference", "description", "causality", "variability", "initial")
            if sv.get(k) is not None})
        if tag == "Enumeration":
            el.set("declaredType", fmi3_type_name(v["name"]))
        for key in ("unit", "displayUnit", "min", "max", "start"):
            if typed.get(key) is not None:
                el.set(key, typed.get(key))

    structure = ET.SubElement(root, "ModelStructure")
    old = src.find("ModelStructure")

    def vr_list(indices: str | None) -> str:  # FMI 2 indices (1-based) -> value references
        return " ".join(str(vrs[int(i) - 1]) for i in (indices or "").split())

    for kind, tag in (("Outputs", "Output"), ("InitialUnknowns", "InitialUnknown")):
        for u in old.find(kind):
            el = ET.SubElement(structure, tag, valueReference=str(vrs[int(u.get("index")) - 1]))
            if u.get("dependencies") is not None:
                el.set("dependencies", vr_list(u.get("dependencies")))
                el.set("dependenciesKind", u.get("dependenciesKind") or "")
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True), time_vr


def fmi3_headers() -> Path:
    """The FMI 3.0 C headers (fmi3Functions.h and the two it includes), from fmpy's c-code
    folder (fmpy: the ``fmu`` extra); raises with what to install."""
    try:
        import fmpy
    except ImportError as e:
        raise RuntimeError("building GearPair3.fmu needs the FMI 3 headers that ship with "
                           "fmpy: pip install 'fmpy>=0.3.20,<0.4' (the fmu extra)") from e
    folder = Path(fmpy.__file__).parent / "c-code"
    if not (folder / "fmi3Functions.h").is_file():
        raise RuntimeError(f"fmpy {fmpy.__version__} has no fmi3Functions.h in {folder}")
    return folder


def compile_fmi3_layer(xml: bytes, spec: list[dict], gp, workdir: Path, time_vr: int,
                       progress=lambda msg: None, win64: bool = False) -> dict[str, bytes]:
    """GearPair3.fmu's binaries by platform (``linux64``, with ``win64`` also ``win64``): the
    generic FMI 3 layer (fmu_src/c/fmi3Functions.c) with the model part, the variable table
    (`fmu_config.config_h` of GearPair.fmu's modelDescription ``xml``, so the two FMUs share
    it) and the engine's object, the same as GearPair.fmu's (`gearpair.aot`, cached by the
    engine's sources). ``time_vr``: the value reference of ``time``
    (`fmi3_model_description`)."""
    fmu_config = _fmu_config()
    model2 = ET.fromstring(xml).find("CoSimulation").get("modelIdentifier")
    (workdir / "config.h").write_text(fmu_config.config_h(xml, spec, model2 + INNER_SUFFIX))
    aot = importlib.import_module(gp.__name__ + ".aot")
    t0 = time.perf_counter()
    made = aot.write_engine(workdir, path=str(PACKAGE.parent), win64=win64)
    how = "from the cache" if made["cached"] else "compiled"
    progress(f"GearPair3.fmu: the engine's object {how} in {time.perf_counter() - t0:.0f} s")
    (workdir / "gearpair_config.h").write_text(fmu_config.gearpair_config_h(spec, gp))
    flags = ["-O2", "-std=c11", "-shared", "-Wall", "-Wextra", "-Werror", f"-I{workdir}",
             f"-I{SHIM_SRC}", f"-I{fmi3_headers()}", f"-DMODEL_TIME_VR={time_vr}u"]
    lib = workdir / f"{FMI3_MODEL}.so"
    builds = {"linux64": [c_compiler(), *flags, "-fPIC", "-fvisibility=hidden", "-o", str(lib),
                          *(str(SHIM_SRC / f) for f in FMI3_SOURCES), made["object"],
                          "-Wl,-z,nodelete", "-Wl,--no-undefined", "-ldl", "-lm", "-lpthread"]}
    if win64:
        dll = workdir / f"{FMI3_MODEL}.dll"
        builds["win64"] = [win64_compiler() or WIN64_CC, *flags, "-D__USE_MINGW_ANSI_STDIO=1",
                           '-DGP_PLATFORM="x86_64-windows"', "-o", str(dll),
                           *(str(SHIM_SRC / f) for f in FMI3_WIN64_SOURCES),
                           made["object_win64"], "-static-libgcc", "-Wl,--no-undefined",
                           "-Wl,--no-insert-timestamp", "-s"]
    out = {}
    for platform, cmd in builds.items():
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"compiling GearPair3.fmu's {platform} binary failed:\n"
                               f"{' '.join(cmd)}\n{r.stderr}")
        out[platform] = Path(cmd[cmd.index("-o") + 1]).read_bytes()
    other = [d for d in pe_imports(out["win64"]) if d.lower() not in WIN64_SYSTEM_DLLS] \
        if win64 else []
    if other:
        raise RuntimeError(f"GearPair3.fmu's win64 binary imports {', '.join(other)}")
    return out


def _fmi3_documentation(page: bytes) -> bytes:
    """GearPair.fmu's documentation page, said of the FMI 3.0 build."""
    text = page.decode("utf-8").replace(
        "<title>GearPair FMU</title>", "<title>GearPair3 FMU (FMI 3.0)</title>")
    note = ("<p><strong>GearPair3.fmu</strong> is the FMI 3.0 co-simulation build of "
            "GearPair.fmu: the same model, variables, value references and units (plus the "
            "independent variable <code>time</code>); the integer-coded choices are "
            "Enumerations (set and got as Int64). Where this page names an fmi2 function, "
            "read its fmi3 counterpart. It provides Event Mode (<code>hasEventMode</code>) "
            "and may return early from <code>fmi3DoStep</code> at a contact event "
            "(<code>mightReturnEarlyFromDoStep</code>; docs/fmu.md of the project).</p>\n")
    head = text.index("</h1>") + len("</h1>\n")
    text = text[:head] + note + text[head:].replace(
        "FMI 2.0 co-simulation FMU", "FMI 3.0 co-simulation FMU", 1)
    return text.encode("utf-8")


def build_fmi3(fmu: Path, spec: list[dict], gp, dest: Path,
               progress=lambda msg: None) -> Path:
    """Write ``dest`` (GearPair3.fmu) from the finished GearPair.fmu ``fmu``: its
    modelDescription as FMI 3.0 (`fmi3_model_description`), the FMI 3 layer's binaries for
    the platforms GearPair.fmu has (`compile_fmi3_layer`; ``x86_64-linux`` beside pythonfmu's
    library for the reference engine, ``x86_64-windows`` when GearPair.fmu has win64), and
    its resources and documentation."""
    with zipfile.ZipFile(fmu) as z:
        xml = z.read("modelDescription.xml")
        names = z.namelist()
        model2 = ET.fromstring(xml).find("CoSimulation").get("modelIdentifier")
        inner = z.read(f"binaries/linux64/{model2}{INNER_SUFFIX}")
        kept = {n: z.read(n) for n in names if n.startswith(("resources/", "documentation/"))}
    xml3, time_vr = fmi3_model_description(xml, spec)
    win64 = f"binaries/win64/{model2}.dll" in names
    progress(f"compiling GearPair3.fmu's FMI 3 layer ({'linux64, win64' if win64 else 'linux64'}"
             ")")
    with tempfile.TemporaryDirectory(prefix="gearpair_fmi3_") as tmp:
        binaries = compile_fmi3_layer(xml, spec, gp, Path(tmp), time_vr, progress, win64)
    if "documentation/index.html" in kept:
        kept["documentation/index.html"] = _fmi3_documentation(kept["documentation/index.html"])
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", xml3)
        for platform, data in binaries.items():
            folder, suffix = FMI3_PLATFORM[platform]
            z.writestr(f"binaries/{folder}/{FMI3_MODEL}{suffix}", data)
        z.writestr(f"binaries/x86_64-linux/{model2}{INNER_SUFFIX}", inner)
        for name, data in kept.items():
            z.writestr(name, data)
    return dest


# -- documentation ----------------------------------------------------------------------------
def _cell(x) -> str:
    if x is None:
        return ""
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, float):
        return f"{x:.6g}"
    return html.escape(str(x))


def render_documentation(spec: list[dict], choices: dict) -> str:
    def table(rows):
        head = ("<tr><th>Name</th><th>Type</th><th>Unit</th><th>Display unit</th>"
                "<th>Start</th><th>Min</th><th>Max</th><th>Description</th></tr>")
        body = "\n".join(
            f"<tr><td><code>{html.escape(v['name'])}</code></td><td>{v['type']}</td>"
            f"<td>{_cell(v['unit'])}</td><td>{_cell(v['display_unit'])}</td>"
            f"<td>{_cell(v['start'])}</td><td>{_cell(v['min'])}</td><td>{_cell(v['max'])}</td>"
            f"<td>{html.escape(v['description'])}</td></tr>" for v in rows)
        return f"<table>\n{head}\n{body}\n</table>"

    switch_names = set(choices) | {"separation", "v_eps", "rtol"}
    ins = [v for v in spec if v["causality"] == "input"]
    outs = [v for v in spec if v["causality"] == "output"]
    pars = [v for v in spec if v["causality"] == "parameter" and v["name"] not in switch_names]
    sws = [v for v in spec if v["name"] in switch_names]
    codes = "\n".join(
        f"<li><code>{n}</code> ({field}): "
        + ", ".join(f"{i} = <code>{c}</code>" for i, c in enumerate(cs)) + "</li>"
        for n, (field, cs) in choices.items())
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>GearPair FMU</title>
<style>
body {{ font-family: sans-serif; max-width: 70em; margin: 2em auto; line-height: 1.4; }}
table {{ border-collapse: collapse; margin: 1em 0; }}
th, td {{ border: 1px solid #bbb; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }}
th {{ background: #eee; }}
</style>
</head>
<body>
<h1>GearPair: spur gear pair dynamics with tooth separation and stick-slip</h1>
<p>FMI 2.0 co-simulation FMU of a spur gear pair after Xun, Dai &amp; Wang (2023): two gears
with translational supports along the line of action, a load shaft on gear 2, time-varying
mesh stiffness, tooth separation and tooth friction with exact switching between slip and
stick. Gear 1 is driven at the shaft speed <code>speed</code> (its nominal rotation) with
the torque <code>torque</code>; the FMU returns the dynamic transmission error, the mesh and
friction forces, the torques and the shaft speeds. All values are SI; display units (rpm,
um, kN, mm, deg) are declared for tools.</p>

<h2>Using it</h2>
<ul>
<li>Default experiment: 0 to 0.5 s, communication step 1e-4 s. Inside every
<code>fmi2DoStep</code> the engine integrates with the inputs held (zero-order hold) to
exactly <code>currentCommunicationPoint + communicationStepSize</code>, locating every
contact switch (separation, slip reversal, stick, break-away) within the step. Coarser
communication steps are therefore accurate; the step figures
(<code>stick_fraction</code>, <code>separation_fraction</code>, <code>mesh_force_max</code>,
<code>n_events</code>) summarize what happened inside the step.</li>
<li>At initialization the deflections start at static equilibrium under the input torque
(no start-up transient from zero). The first <code>fmi2DoStep</code> starts the motion at
<code>startTime</code> (of <code>fmi2SetupExperiment</code>) with the inputs then set.</li>
<li>Variable communication step sizes, <code>fmi2GetFMUstate</code>/<code>fmi2SetFMUstate</code>
and state serialization are supported; a serialized state can be restored into a fresh
instance of this FMU.</li>
<li>The default engine (<code>engine</code> = 0) is compiled into the FMU's binaries and
needs nothing on the target machine, no Python. Binaries: <code>binaries/linux64</code>
(Linux x86_64) and, from a builder with mingw-w64, <code>binaries/win64</code> (Windows
x86_64; KERNEL32 and the C runtime msvcrt only). The scipy reference engine
(<code>engine</code> = 1) runs Python code (pythonfmu), in the linux64 binary only; the win64
binary refuses it with an error at <code>fmi2ExitInitializationMode</code>. It needs Python 3
with numpy, scipy, pythonfmu and numba (<code>resources/requirements.txt</code>). Python
hosts (fmpy, libcosimpy, ecospy) use their own interpreter; other hosts (C/C++ masters) need
nothing set: the FMU loads the Python that built it (<code>resources/python.txt</code>), or
the python executable that the environment variable <code>GEARPAIR_PYTHON</code> names. With
logging on, the first message says which Python and engine run.</li>
</ul>

<h2>Inputs</h2>
{table(ins)}
<h2>Outputs</h2>
<p>Instantaneous values at the end of the last communication step, except the step figures
(fractions, peak force and event count), which refer to the whole step. Before the first
step they describe the initial instant.</p>
{table(outs)}
<h2>Effect switches (structural parameters)</h2>
<p>An effect switched off removes its terms from the model (it is not a multiplier). Integer
codes:</p>
<ul>
{codes}
</ul>
{table(sws)}
<h2>Gear data (parameters)</h2>
<p>Defaults are Table 1 of the paper, except <code>kr2</code>, which the paper does not give
(chosen so that the slip model's first natural frequency is 32 Hz with the mean mesh
stiffness). Damping coefficients follow from <code>damping_ratio</code>; base radii are
r<sub>b</sub> = m z cos(alpha) / 2 (Eq. (5)).</p>
{table(pars)}

<h2>Model equations (references to the paper)</h2>
<ul>
<li>Eq. (3): mesh deflection delta along the line of action; output <code>dte</code>.</li>
<li>Eq. (5): base radii, and the rotations expressed as displacements on the base circles.</li>
<li>Eq. (8): tooth separation: mesh force and mesh damping vanish for delta &lt; 0
(<code>separation</code> = true).</li>
<li>Eq. (12): relative sliding velocity of each tooth pair (<code>sliding</code> = 0);
<code>sliding</code> = 1 adds the rotational vibration.</li>
<li>Eq. (14): the switching conditions between slip and stick
(<code>friction_law</code> = 3).</li>
<li>Eq. (16): elastic mesh force km Theta(delta) delta; output <code>mesh_force</code>.</li>
<li>Eqs. (19)-(21): the paper's kinematic tie of stuck surfaces (<code>stick_tie</code> = 1);
<code>stick_tie</code> = 0 holds the sliding velocity at exactly zero.</li>
</ul>

<h2>Limits and error handling</h2>
<ul>
<li>The FMU follows the FMI 2.0 co-simulation state machine: a call not allowed in the
current mode (e.g. <code>fmi2DoStep</code> before <code>fmi2ExitInitializationMode</code>)
returns fmi2Error with a log message and changes nothing.</li>
<li>Inputs and parameters are checked when they are set: a NaN, infinite or out-of-range
value (ranges above), an integer code outside its choices, or a parameter set after
initialization (all parameters are fixed) makes the <code>fmi2Set*</code> call return
fmi2Error; the value is not taken and the variable keeps its old value.</li>
<li>Combinations of parameters the model cannot run (e.g. <code>dof</code> = 1 with
<code>friction_law</code> = 3 needs <code>sliding</code> = 1; <code>backlash</code> &gt; 0
needs <code>separation</code>; a contact ratio below 1) make
<code>fmi2ExitInitializationMode</code> return fmi2Error; the instance stays in
initialization mode, so the master may correct a parameter and call it again (or reset).</li>
<li>Steps must start at the FMU's current time (the first one at <code>startTime</code>; or
restore an FMU state first) and have a positive, finite size; otherwise fmi2Error with the
state unchanged.</li>
<li>If the integrator fails inside a step, the step returns fmi2Discard and the state is
that of the step start (lastSuccessfulTime); the step may be retried.</li>
<li>Every fmi2Error of this FMU comes from a refused call that changed nothing, so the
master may go on after correcting the call (the standard only promises
<code>fmi2SetFMUstate</code>, <code>fmi2Reset</code> or <code>fmi2FreeInstance</code>).</li>
<li>Warnings and errors always reach the master's logger, whatever <code>loggingOn</code>
says; information messages follow <code>loggingOn</code> and
<code>fmi2SetDebugLogging</code>.</li>
<li>A serialized FMU state carries a checksum: a truncated or altered one is refused by
<code>fmi2DeSerializeFMUstate</code> with fmi2Error.</li>
<li>The integrator tolerance is the parameter <code>rtol</code>; the tolerance a master
passes to <code>fmi2SetupExperiment</code> is not used. With <code>friction_law</code> off
and <code>stiffness_model</code> constant or rectangular the equations have constant
coefficients between switches and are stepped exactly (matrix exponential), much cheaper than
with a time-varying stiffness.</li>
<li>Inputs are held over the step; input derivatives (canInterpolateInputs) are not
supported.</li>
<li>The stiffness law "table" of the Python package is not exposed in the FMU.</li>
</ul>
</body>
</html>
"""


# -- build ------------------------------------------------------------------------------------
def _load_interface(staging: Path, script: Path):
    """Import GearPair.py and the staged gearpair package; return (module, package, spec)."""
    for p in (str(staging), str(script.parent)):
        if p not in sys.path:
            sys.path.insert(0, p)
    mod = importlib.import_module(script.stem)
    gp = mod._import_gearpair(str(staging))
    return mod, gp, mod.interface(gp)


def _describe_python() -> str:
    """``resources/python.txt``: this interpreter's libpython, home, executable and package
    folders (`gearpair_python.describe`), for the C layer of hosts that are not Python."""
    spec = importlib.util.spec_from_file_location("_gearpair_python_build", PYTHON_SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return ("# the Python that built this FMU (build_fmu.py); GEARPAIR_PYTHON overrides it\n"
            + mod.describe())


def _stderr(msg: str) -> None:
    print(f"build_fmu: {msg}", file=sys.stderr, flush=True)


def write_build_record(fmu: Path, script: Path = SCRIPT) -> Path:
    """``<fmu>.build.json`` beside the FMU: this builder and ``fmu_src`` (the slave, the Python
    it loads, the C layer) with their SHA-256, and the FMU's own. `gearpair.scenes.location`
    reads it to tell a stale FMU (one of these files changed after the build) and to rebuild
    it with this builder. The bundled package needs no record: the FMU holds its copy,
    compared file by file."""
    import hashlib
    import json

    def digest(p: Path) -> str:
        return hashlib.sha256(p.read_bytes()).hexdigest()

    fmu_src = SCRIPT.parent  # the slave, the Python it loads, the C layer
    files = dict.fromkeys([Path(__file__).resolve(), Path(script).resolve(),
                           *(p.resolve() for p in sorted(fmu_src.rglob("*"))
                             if p.suffix in (".py", ".c", ".h"))])
    record = {"fmu_sha256": digest(fmu), "builder": str(Path(__file__).resolve()),
              "sources": {str(p): digest(p) for p in files}}
    path = fmu.with_name(fmu.name + ".build.json")
    part = path.with_name(f".{path.name}.{os.getpid()}.part")
    part.write_text(json.dumps(record, indent=1) + "\n")
    part.replace(path)  # whole or not at all for a reader (`gearpair.scenes.location`)
    return path


def build(out: str | Path = "dist", package: str | Path = PACKAGE,
          script: str | Path = SCRIPT, progress=_stderr, win64: bool | None = None) -> Path:
    """Build ``<out>/GearPair.fmu`` and return its path.

    ``progress`` gets one line per step (default: printed to stderr as ``build_fmu: ...``);
    compiling the engine the FMU ships takes about 30 s once per engine source.

    The FMU is assembled in a private folder inside ``out`` and renamed into place when
    complete, then its build record likewise: a process reading ``<out>/GearPair.fmu``
    meanwhile (a run, or a second build) sees the old file or the new one, never a part.

    ``win64``: also ``binaries/win64/GearPair.dll`` (None: when mingw-w64 is there, else the
    FMU holds binaries/linux64 only and ``progress`` says so; True: fail without it).

    ``<out>/GearPair3.fmu``, the FMI 3.0 build of the same FMU (`build_fmi3`), is written
    beside it, before it."""
    from pythonfmu.builder import FmuBuilder

    out, package, script = Path(out).resolve(), Path(package).resolve(), Path(script).resolve()
    if not (package / "params.py").is_file():
        raise FileNotFoundError(f"{package} is not the gearpair package")
    out.mkdir(parents=True, exist_ok=True)
    saved_path, saved_modules = list(sys.path), set(sys.modules)
    try:
        with tempfile.TemporaryDirectory(prefix="gearpair_fmu_") as tmp, \
                tempfile.TemporaryDirectory(prefix=".GearPair.fmu.", dir=out) as part:
            progress(f"staging {package.name} and {script.name}")
            staging = Path(tmp) / "resources"
            staging.mkdir()
            shutil.copytree(package, staging / "gearpair",
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.pyo"))
            (staging / "requirements.txt").write_text(requirements())
            mod, gp, spec = _load_interface(staging, script)
            docs = Path(tmp) / "documentation"
            docs.mkdir()
            (docs / "index.html").write_text(render_documentation(spec, mod.choices(spec)),
                                             encoding="utf-8")
            progress("packing the FMU with pythonfmu")
            fmu = FmuBuilder.build_FMU(
                script, dest=Path(part) / "GearPair.fmu",
                project_files=[staging / "gearpair", staging / "requirements.txt",
                               *(script.parent / f"{m}.py" for m in SLAVE_MODULES)],
                documentation_folder=docs,
                canHandleVariableCommunicationStepSize=True,
                canGetAndSetFMUstate=True, canSerializeFMUstate=True)
            fmu = Path(fmu)
            with zipfile.ZipFile(fmu) as z:
                xml = z.read("modelDescription.xml")
            _rewrite_zip(fmu, {"modelDescription.xml": complete_model_description(xml, spec)})
            progress(f"compiling the FMU's C layer ({Path(c_compiler()).name})")
            add_c_layer(fmu, spec, gp, progress, win64=win64)
            fmu3 = build_fmi3(fmu, spec, gp, Path(part) / f"{FMI3_MODEL}.fmu", progress)
            fmu3.replace(out / fmu3.name)
            fmu = Path(fmu).replace(out / "GearPair.fmu")
            write_build_record(fmu, script)
    finally:
        # The builder imports GearPair and gearpair from temporary folders: forget them so
        # that an FMU instantiated later in this process imports its own bundled copy.
        sys.path[:] = saved_path
        for name in set(sys.modules) - saved_modules:
            if name.partition(".")[0] in ("GearPair", "gearpair", "_gearpair_fmu"):
                del sys.modules[name]
    return fmu


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="dist", help="output folder (default: dist)")
    ap.add_argument("--package", default=str(PACKAGE), help=argparse.SUPPRESS)
    ap.add_argument("--no-win64", action="store_true",
                    help="binaries/linux64 only, even where mingw-w64 is there")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    fmu = build(args.out, package=args.package, win64=False if args.no_win64 else None)
    print(f"built {fmu} and {FMI3_MODEL}.fmu (FMI 3.0) in {time.perf_counter() - t0:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
