"""The driveline system, described once: components, connections, parameters, the SSD.

    Motor --speed--> GearPair.speed           GearPair.output_torque --> Load.torque
    Motor <--load_torque-- GearPair.input_torque     GearPair.load_speed <--speed-- Load

Each shaft carries a speed one way and a torque back (power flows both ways). The shaft
compliances live inside ``GearPair.fmu``: the input shaft ``kr1`` (motor end at the motor
speed) and the load shaft ``kr2`` (far end at the load speed). ``build.py`` writes this
description as ``SystemStructure.ssd`` (SSP 1.0) with the parameters as inline parameter
bindings; the runners read it back (fmpy's SSP simulator does not apply bindings itself).

Shared by build.py, the three runners, compare.py and plot.py; import the runners through
`sibling` (their module names also exist in examples/hosts).
"""

from __future__ import annotations

import copy
import importlib.util
import math
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
RPM = 2.0 * math.pi / 60.0  # rad/s per r/min
PARAMETER_SET = "driveline"  # the name of every component's parameter set (ecos needs it)
GEAR_J1, GEAR_J2 = 0.139, 4.799  # kg.m2, GearParams defaults: lumped into motor and load

# component -> (FMU file in resources/, parameters). Plot scenario: a start-up from
# standstill through the stick-slip range (below about 300 r/min of gear 1) to a steady
# speed of about 350 r/min, then a load increase at 2 s that brings it back to about 284 r/min.
PARAMETERS: dict[str, dict[str, float | int | bool]] = {
    "Motor": {
        "J": 2.0 + GEAR_J1,        # kg.m2: rotor 2.0 + gear 1
        "T_stall": 12000.0,        # N.m: droop 12000 / w_noload = 229 N.m.s/rad
        "w_noload": 500.0 * RPM,   # rad/s
        "T_max": 12000.0,          # N.m: torque limit (here not below the droop line)
        "w_start": 0.0,            # rad/s
    },
    "GearPair": {
        "kr1": 1.0e8,              # N/m on rb1: input shaft 8.65e5 N.m/rad
        "load_speed_input": True,  # the load shaft ends at Load.speed
        "friction_law": 3,         # stick_slip
        "rtol": 1e-6,
        "torque": 0.0,             # N.m: the shaft kr1 drives gear 1, not this input
        "speed": 0.0,              # rad/s: start values of the connected inputs
        "load_speed": 0.0,
    },
    "Load": {
        "J": 400.0 + GEAR_J2,      # kg.m2: drum 400 + gear 2
        "c": 50.0,                 # N.m.s/rad
        "T_load": 8000.0,          # N.m
        "T_step": 4000.0,          # N.m, added at t_step
        "t_step": 2.0,             # s
        "w_start": 0.0,            # rad/s
    },
}
PLOT_STOP_TIME = 3.0  # s
# A quick variant for tests (0.35 s): light load and a stiffer droop settle in about 0.1 s
# (time constant 14 ms), the load steps up at 0.2 s.
QUICK: dict[str, dict[str, float]] = {
    "Motor": {"T_stall": 24000.0},                       # droop 458 N.m.s/rad
    "Load": {"J": 20.0 + GEAR_J2, "t_step": 0.2},
}
QUICK_STOP_TIME = 0.35  # s
FMU_FILES = {"Motor": "Motor.fmu", "GearPair": "GearPair.fmu", "Load": "Load.fmu"}

# component -> connectors: (name, kind, type, unit). Extra outputs are listed for recording.
CONNECTORS: dict[str, tuple[tuple[str, str, str, str | None], ...]] = {
    "Motor": (("load_torque", "input", "Real", "N.m"),
              ("speed", "output", "Real", "rad/s"),
              ("torque", "output", "Real", "N.m")),
    "GearPair": (("speed", "input", "Real", "rad/s"),
                 ("load_speed", "input", "Real", "rad/s"),
                 ("input_torque", "output", "Real", "N.m"),
                 ("output_torque", "output", "Real", "N.m"),
                 ("dte", "output", "Real", "m"),
                 ("mesh_force", "output", "Real", "N"),
                 ("gear1_speed", "output", "Real", "rad/s"),
                 ("stick_fraction", "output", "Real", "1"),
                 ("separation_fraction", "output", "Real", "1"),
                 ("contact_state", "output", "Integer", None)),
    "Load": (("torque", "input", "Real", "N.m"),
             ("speed", "output", "Real", "rad/s"),
             ("resisting_torque", "output", "Real", "N.m")),
}
# (from component, output) -> (to component, input)
CONNECTIONS: tuple[tuple[str, str, str, str], ...] = (
    ("Motor", "speed", "GearPair", "speed"),
    ("GearPair", "input_torque", "Motor", "load_torque"),
    ("GearPair", "output_torque", "Load", "torque"),
    ("Load", "speed", "GearPair", "load_speed"),
)
# recorded signals, "Component.variable": every output connector
SIGNALS: tuple[str, ...] = tuple(f"{c}.{n}" for c, rows in CONNECTORS.items()
                                 for n, kind, _t, _u in rows if kind == "output")
INTEGER_SIGNALS = frozenset(f"{c}.{n}" for c, rows in CONNECTORS.items()
                            for n, _k, t, _u in rows if t == "Integer")
# units used by connectors and parameters: SI base-unit exponents
UNITS = {"N.m": {"kg": 1, "m": 2, "s": -2}, "rad/s": {"rad": 1, "s": -1}, "m": {"m": 1},
         "N": {"kg": 1, "m": 1, "s": -2}, "1": {}, "kg.m2": {"kg": 1, "m": 2}, "s": {"s": 1},
         "N/m": {"kg": 1, "s": -2}, "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1}}
PARAMETER_UNITS = {("Motor", "J"): "kg.m2", ("Motor", "T_stall"): "N.m",
                   ("Motor", "w_noload"): "rad/s", ("Motor", "T_max"): "N.m",
                   ("Motor", "w_start"): "rad/s", ("GearPair", "kr1"): "N/m",
                   ("GearPair", "torque"): "N.m", ("GearPair", "speed"): "rad/s",
                   ("GearPair", "load_speed"): "rad/s", ("GearPair", "rtol"): "1",
                   ("Load", "J"): "kg.m2", ("Load", "c"): "N.m.s/rad", ("Load", "T_load"): "N.m",
                   ("Load", "T_step"): "N.m", ("Load", "t_step"): "s",
                   ("Load", "w_start"): "rad/s"}

NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues"}


def merged_parameters(overrides: dict[str, dict] | None = None) -> dict[str, dict]:
    """`PARAMETERS` with ``{component: {name: value}}`` overrides applied (a new dict)."""
    params = copy.deepcopy(PARAMETERS)
    for comp, values in (overrides or {}).items():
        if comp not in params:
            raise KeyError(f"unknown component {comp!r}; known: {sorted(params)}")
        params[comp].update(values)
    return params


def _typed_element(parent: ET.Element, prefix: str, value, unit: str | None) -> None:
    if isinstance(value, bool):
        ET.SubElement(parent, f"{{{NS[prefix]}}}Boolean", value="true" if value else "false")
    elif isinstance(value, int):
        ET.SubElement(parent, f"{{{NS[prefix]}}}Integer", value=str(value))
    else:
        attrs = {"value": repr(float(value))}
        if unit:
            attrs["unit"] = unit
        ET.SubElement(parent, f"{{{NS[prefix]}}}Real", attrs)


def ssd_xml(params: dict[str, dict], stop_time: float, step: float) -> bytes:
    """SystemStructure.ssd (SSP 1.0) for the given parameters.

    Parameters
    ----------
    params : ``{component: {name: value}}``, written as each component's inline parameter
        set `PARAMETER_SET` (bool -> Boolean, int -> Integer, float -> Real with its unit)
    stop_time : s, DefaultExperiment stop time
    step : s, communication step, in the Open Simulation Platform annotation that libcosim
        reads when it is given no step size

    Returns
    -------
    bytes : the XML document
    """
    for prefix, uri in NS.items():
        ET.register_namespace(prefix, uri)
    ET.register_namespace("osp", "http://opensimulationplatform.com/SSP/OSPAnnotations")
    ssd, ssc, ssv = (f"{{{NS[p]}}}" for p in ("ssd", "ssc", "ssv"))
    root = ET.Element(f"{ssd}SystemStructureDescription", name="GearPairDriveline",
                      version="1.0")
    system = ET.SubElement(root, f"{ssd}System", name="Driveline",
                           description="motor - GearPair - load, power flowing both ways")
    elements = ET.SubElement(system, f"{ssd}Elements")
    for comp, rows in CONNECTORS.items():
        el = ET.SubElement(elements, f"{ssd}Component", name=comp,
                           type="application/x-fmu-sharedlibrary",
                           source=f"resources/{FMU_FILES[comp]}")
        conns = ET.SubElement(el, f"{ssd}Connectors")
        for name, kind, typ, unit in rows:
            c = ET.SubElement(conns, f"{ssd}Connector", name=name, kind=kind)
            ET.SubElement(c, f"{ssc}{typ}", {"unit": unit} if unit else {})
        bindings = ET.SubElement(el, f"{ssd}ParameterBindings")
        values = ET.SubElement(ET.SubElement(bindings, f"{ssd}ParameterBinding"),
                               f"{ssd}ParameterValues")
        pset = ET.SubElement(values, f"{ssv}ParameterSet", version="1.0", name=PARAMETER_SET)
        plist = ET.SubElement(pset, f"{ssv}Parameters")
        for name, value in params[comp].items():
            p = ET.SubElement(plist, f"{ssv}Parameter", name=name)
            _typed_element(p, "ssv", value, PARAMETER_UNITS.get((comp, name)))
    conns = ET.SubElement(system, f"{ssd}Connections")
    for a, out, b, inp in CONNECTIONS:
        ET.SubElement(conns, f"{ssd}Connection", startElement=a, startConnector=out,
                      endElement=b, endConnector=inp)
    units = ET.SubElement(root, f"{ssd}Units")
    for name, exps in UNITS.items():
        u = ET.SubElement(units, f"{ssc}Unit", name=name)
        ET.SubElement(u, f"{ssc}BaseUnit", {k: str(v) for k, v in exps.items()})
    exp = ET.SubElement(root, f"{ssd}DefaultExperiment", startTime="0.0",
                        stopTime=repr(float(stop_time)))
    ann = ET.SubElement(ET.SubElement(exp, f"{ssd}Annotations"), f"{ssc}Annotation",
                        type="com.opensimulationplatform")
    algo = ET.SubElement(ann, "{http://opensimulationplatform.com/SSP/OSPAnnotations}Algorithm")
    ET.SubElement(algo, "{http://opensimulationplatform.com/SSP/OSPAnnotations}"
                  "FixedStepAlgorithm", baseStepSize=repr(float(step)))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def read_parameters(ssp: str | Path) -> dict[str, dict]:
    """The inline parameter bindings of an SSP (``.ssp`` archive or ``.ssd`` file), typed."""
    ssp = Path(ssp)
    if ssp.suffix == ".ssp":
        with zipfile.ZipFile(ssp) as z:
            root = ET.fromstring(z.read("SystemStructure.ssd"))
    else:
        root = ET.parse(ssp).getroot()
    out: dict[str, dict] = {}
    for comp in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
        values = out.setdefault(comp.get("name"), {})
        for p in comp.iterfind("ssd:ParameterBindings/ssd:ParameterBinding/ssd:ParameterValues/"
                               "ssv:ParameterSet/ssv:Parameters/ssv:Parameter", NS):
            typed = p[0]
            kind, text = typed.tag.split("}")[1], typed.get("value")
            values[p.get("name")] = (float(text) if kind == "Real" else int(text)
                                     if kind == "Integer" else text in ("true", "1"))
    return out


def mesh_ratio(params: dict[str, dict]) -> float:
    """z1/z2 of the gear pair (GearParams defaults 33/80 unless overridden)."""
    gp = params.get("GearPair", {})
    return float(gp.get("z1", 33)) / float(gp.get("z2", 80))


def steady_state(params: dict[str, dict], extra_load: float = 0.0) -> dict[str, float]:
    """Steady operating point from the characteristic, with the mesh losses neglected.

    Solves ``T_m(w) = r (T_load + extra_load + c r w)`` with ``r = z1/z2`` and the load
    turning at ``r w``.

    Parameters
    ----------
    params : ``{component: {name: value}}`` as `merged_parameters` or `read_parameters`
    extra_load : N.m, added to the load torque (e.g. the load step ``T_step``)

    Returns
    -------
    dict : ``motor_speed``, ``load_speed`` (rad/s), ``motor_torque`` (N.m, what the gear
        pair draws from the motor) and ``load_torque`` (N.m, on the load shaft)
    """
    m, ld, r = params["Motor"], params["Load"], mesh_ratio(params)
    t_load = ld["T_load"] + extra_load
    k = m["T_stall"] / m["w_noload"]
    w = (m["T_stall"] - r * t_load) / (k + ld["c"] * r * r)  # on the droop line
    t_m = r * (t_load + ld["c"] * r * w)
    if abs(t_m) > m["T_max"]:  # on the torque limit instead
        t_m = math.copysign(m["T_max"], t_m)
        w = (t_m / r - t_load) / (ld["c"] * r) if ld["c"] > 0 else math.nan
    return {"motor_speed": w, "load_speed": r * w, "motor_torque": t_m,
            "load_torque": t_m / r}


def sibling(name: str):
    """Import ``examples/driveline/<name>.py`` under the unique name ``driveline_<name>``."""
    key = f"driveline_{name}"
    if key not in sys.modules:
        spec = importlib.util.spec_from_file_location(key, HERE / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[key] = mod
        spec.loader.exec_module(mod)
    return sys.modules[key]
