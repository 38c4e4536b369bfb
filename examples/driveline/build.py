"""Build the driveline example: Motor.fmu, Load.fmu, GearPair.fmu and driveline.ssp.

    python examples/driveline/build.py [--out build/driveline] [--stop-time 4] [--step 1e-4]

Motor and Load are pythonfmu slaves (``motor.py``, ``load.py``); their modelDescription is
completed here with units, ranges and the model structure that pythonfmu leaves out, and
their binary gets the project's C layer (``build_fmu.add_c_layer``) like GearPair.fmu.
GearPair.fmu comes from ``build_fmu.build`` (or an existing file). The SSP archive holds
``SystemStructure.ssd`` (written by ``driveline_system.ssd_xml``) and the three FMUs in
``resources/``; ``SystemStructure.ssd`` is also written next to it for reading.
"""

from __future__ import annotations

import argparse
import importlib.util
import shutil
import sys
import time
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import driveline_system as ds  # noqa: E402

DISPLAY_UNITS = {"rad/s": ("rpm", 60.0 / (2.0 * 3.141592653589793))}
_ORDER = ("ModelExchange", "CoSimulation", "UnitDefinitions", "TypeDefinitions",
          "LogCategories", "DefaultExperiment", "VendorAnnotations", "ModelVariables",
          "ModelStructure")


def _load_by_path(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def complete_model_description(xml: bytes, variables: tuple[tuple, ...]) -> bytes:
    """modelDescription.xml of a Motor/Load slave completed from its ``VARIABLES`` table.

    Adds unit definitions, units, display units, min/max and start values, capability flags
    and the model structure: outputs are states (speed) or functions of states, so they do
    not depend directly on the inputs of the same instant (no direct feedthrough).
    """
    root = ET.fromstring(xml)
    cosim = root.find("CoSimulation")
    for flag in ("canHandleVariableCommunicationStepSize", "canGetAndSetFMUstate",
                 "canSerializeFMUstate"):
        cosim.set(flag, "true")
    for tag in ("UnitDefinitions", "ModelStructure"):
        for el in root.findall(tag):
            root.remove(el)
    rows = {row[0]: row for row in variables}
    units = ET.Element("UnitDefinitions")
    for name in sorted({row[2] for row in variables if row[2]}):
        u = ET.SubElement(units, "Unit", name=name)
        ET.SubElement(u, "BaseUnit", {k: str(e) for k, e in ds.UNITS[name].items()})
        if name in DISPLAY_UNITS:
            dname, factor = DISPLAY_UNITS[name]
            ET.SubElement(u, "DisplayUnit", name=dname, factor=repr(factor))
    root.append(units)
    index = {}
    for i, sv in enumerate(root.find("ModelVariables").findall("ScalarVariable"), start=1):
        name, causality, unit, dunit, lo, hi, start, doc = rows[sv.get("name")]
        index[name] = i
        sv.set("description", doc)
        real = sv.find("Real")
        real.set("unit", unit)
        if dunit:
            real.set("displayUnit", dunit)
        for key, x in (("min", lo), ("max", hi)):
            if x is not None:
                real.set(key, repr(float(x)))
        if start is not None:
            real.set("start", repr(float(start)))
        elif "start" in real.attrib:
            del real.attrib["start"]
    structure = ET.SubElement(root, "ModelStructure")
    outs = ET.SubElement(structure, "Outputs")
    init = ET.SubElement(structure, "InitialUnknowns")
    # initial outputs follow from the parameters alone (no input): an initial value that
    # declared all inputs (no dependencies attribute) made masters see algebraic loops
    params = [str(index[name]) for name, causality, *_ in variables if causality == "parameter"]
    for name, causality, *_ in variables:
        if causality == "output":
            ET.SubElement(outs, "Unknown", index=str(index[name]), dependencies="",
                          dependenciesKind="")
            ET.SubElement(init, "Unknown", index=str(index[name]), dependencies=" ".join(params),
                          dependenciesKind=" ".join(["dependent"] * len(params)))
    root[:] = sorted(root, key=lambda el: _ORDER.index(el.tag))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def build_slave(script: Path, out: Path) -> Path:
    """Build one pythonfmu slave (``motor.py`` or ``load.py``) into ``out``; return the FMU."""
    from pythonfmu.builder import FmuBuilder

    saved_path, saved_modules = list(sys.path), dict(sys.modules)
    try:
        # the builder imports the script under its stem: make sure no other module of that
        # name is picked up, and forget it afterwards
        sys.modules.pop(script.stem, None)
        fmu = Path(FmuBuilder.build_FMU(script, dest=out,
                                        canHandleVariableCommunicationStepSize=True,
                                        canGetAndSetFMUstate=True, canSerializeFMUstate=True))
    finally:
        sys.path[:] = saved_path
        sys.modules.pop(script.stem, None)
        if script.stem in saved_modules:
            sys.modules[script.stem] = saved_modules[script.stem]
    variables = _load_by_path(f"driveline_{script.stem}_interface", script).VARIABLES
    tmp = fmu.with_suffix(".tmp")
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = complete_model_description(data, variables)
            zout.writestr(item.filename, data)
    tmp.replace(fmu)
    # the project's C layer over pythonfmu's binary, as in GearPair.fmu: FMI state machine,
    # range checks, errors always logged, clean exit (docs/hosts.md)
    _load_by_path("driveline_build_fmu", ROOT / "build_fmu.py").add_c_layer(fmu)
    return fmu


def write_ssp(out: Path, params: dict[str, dict], stop_time: float, step: float) -> Path:
    """Write ``SystemStructure.ssd`` and ``driveline.ssp`` (with the FMUs found in ``out``)."""
    ssd = ds.ssd_xml(params, stop_time, step)
    (out / "SystemStructure.ssd").write_bytes(ssd)
    ssp = out / "driveline.ssp"
    with zipfile.ZipFile(ssp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("SystemStructure.ssd", ssd)
        for fmu in ds.FMU_FILES.values():
            z.write(out / fmu, arcname=f"resources/{fmu}")
    return ssp


def build(out: str | Path = ROOT / "build" / "driveline", overrides: dict | None = None,
          gearpair_fmu: str | Path | None = None, stop_time: float = 4.0,
          step: float = 1e-4) -> Path:
    """Build the three FMUs into ``out`` and write the SSP; return the ``.ssp`` path.

    Parameters
    ----------
    out : folder for Motor.fmu, Load.fmu, GearPair.fmu, SystemStructure.ssd, driveline.ssp
    overrides : ``{component: {parameter: value}}`` changes to `driveline_system.PARAMETERS`
    gearpair_fmu : an existing GearPair.fmu to copy instead of building one
    stop_time : s, DefaultExperiment stop time written into the SSD
    step : s, communication step written into the SSD (libcosim's default algorithm)
    """
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    for script in ("motor.py", "load.py"):
        build_slave(HERE / script, out)
    target = out / ds.FMU_FILES["GearPair"]
    if gearpair_fmu is not None:
        if Path(gearpair_fmu).resolve() != target:
            shutil.copyfile(gearpair_fmu, target)
    else:
        _load_by_path("driveline_build_fmu", ROOT / "build_fmu.py").build(out)
    return write_ssp(out, ds.merged_parameters(overrides), stop_time, step)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "build" / "driveline"), help="output folder")
    ap.add_argument("--gearpair-fmu", default=None, help="use this GearPair.fmu, do not build")
    ap.add_argument("--stop-time", type=float, default=4.0, help="s (DefaultExperiment)")
    ap.add_argument("--step", type=float, default=1e-4, help="communication step, s")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    ssp = build(args.out, gearpair_fmu=args.gearpair_fmu, stop_time=args.stop_time,
                step=args.step)
    print(f"wrote {ssp} in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
