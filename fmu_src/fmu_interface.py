"""The one declaration of GearPair.fmu's variables (`interface`): names, types, causality,
variability, units, display units, ranges, start values, descriptions and integer codes, in
value-reference order, from the gearpair package's own declarations (`GearParams.describe`,
`gearpair.effects.OPTIONS`, `OperatingPoint`). The slave (``GearPair.py``) registers its
variables from it, ``build_fmu.py`` completes the modelDescription and generates the C
layer's tables (``fmu_config.py``) and the documentation from it. It ships in the FMU's
resources beside the slave.
"""

from __future__ import annotations

import importlib
from typing import Any

# The slave's own choice (not an effect; the effects' choices, codes and ranges come from
# `gearpair.effects.OPTIONS`): the integrator, coded as its index in `gearpair.ENGINES`.
ENGINE_DOC = ("integrator: the engine compiled into the FMU's binary (fast; no Python) or the "
              "scipy yardstick (reference; runs in the Python that built the FMU, or "
              "GEARPAIR_PYTHON)")
# The parameters after GearParams' and the outputs added later, in registration order (value
# references follow it): the effects' FMU parameters (`gearpair.effects.OPTIONS`, "fmu") and the
# slave's own. Append, never reorder: a new effect's parameter goes at the end.
LATER_VARIABLES = ("stiffness_model", "separation", "friction_law", "v_eps", "sliding",
                   "stick_tie", "engine", "backlash", "dof", "load_speed_input", "rtol",
                   "mu_static", "stribeck_velocity", "back_fraction", "mesh_force_mean",
                   "mesh_force_min")

# Display units chosen for parameters by their unit.
_PARAM_DISPLAY_UNIT = {"rad": "deg", "m": "mm"}

# Outputs: name, type, unit, display unit, min, max, description. Their values come from the
# engine's Outputs (instantaneous, at the end of the step) and StepSummary (over the step).
OUTPUTS: tuple[tuple[str, str, str | None, str | None, float | None, float | None, str], ...] = (
    ("dte", "Real", "m", "um", None, None,
     "dynamic transmission error: mesh deflection along the line of action, Eq. (3)"),
    ("mesh_force", "Real", "N", "kN", None, None,
     "elastic mesh force km*Theta(delta)*delta, Eq. (16)"),
    ("friction_force", "Real", "N", None, None, None,
     "total tangential tooth force (sliding or static friction), sum over the pairs"),
    ("contact_state", "Integer", None, None, 0, 3,
     "contact state at the end of the step: 0 separated, 1 slip, 2 stick (any pair stuck), "
     "3 back flanks in contact (backlash > 0)"),
    ("output_torque", "Real", "N.m", None, None, None,
     "torque delivered to the gear 2 shaft"),
    ("input_torque_reaction", "Real", "N.m", None, None, None,
     "torque the mesh exerts back on gear 1 about its axis"),
    ("input_torque", "Real", "N.m", None, None, None,
     "torque the input side delivers into gear 1 (torque input plus input shaft kr1): the "
     "load a driving motor feels"),
    ("gear1_speed", "Real", "rad/s", "rpm", None, None,
     "absolute speed of gear 1 (nominal + vibration)"),
    ("gear2_speed", "Real", "rad/s", "rpm", None, None,
     "absolute speed of gear 2 (nominal + vibration)"),
    ("sliding_velocity", "Real", "m/s", None, None, None,
     "relative sliding velocity of the tooth pair nearest the pitch point"),
    ("stick_fraction", "Real", "1", None, 0.0, 1.0,
     "fraction of the last communication step spent in stick (from located switches)"),
    ("separation_fraction", "Real", "1", None, 0.0, 1.0,
     "fraction of the last communication step with the teeth apart"),
    ("mesh_force_max", "Real", "N", "kN", None, None,
     "greatest elastic mesh force in the last communication step"),
    ("n_events", "Integer", None, None, 0, None,
     "number of state switches located in the last communication step"),
)
# Step figures added later: registered after every other variable (`interface`), so the value
# references of the earlier ones stay as they were; their values are the last three step
# figures in `StepSummary`'s order (`_values_of`, `FastEngine.advance_values`).
APPENDED_OUTPUTS: tuple[tuple[str, str, str | None, str | None, float | None, float | None,
                              str], ...] = (
    ("back_fraction", "Real", "1", None, 0.0, 1.0,
     "fraction of the last communication step with the back flanks in contact (backlash > 0: "
     "contact under a negative torque, not contact loss)"),
    ("mesh_force_mean", "Real", "N", "kN", None, None,
     "time mean of the elastic mesh force over the last communication step (from the "
     "engine's integral over its steps)"),
    ("mesh_force_min", "Real", "N", "kN", None, None,
     "least elastic mesh force in the last communication step"),
)


def interface(gp=None) -> list[dict[str, Any]]:
    """Every FMU variable in registration (value reference) order, as plain dicts.

    Keys: name, type (Real/Integer/Boolean), causality, variability, unit, display_unit, min,
    max, start (None for outputs), description, lo_open, and for an integer-coded choice
    field (what it sets) and codes (the choices in code order, `choices`). The single source
    for the slave's variables, the modelDescription post-processing and the documentation
    page; parameter data come from ``GearParams.describe()``, the effects' from their
    metadata (``gearpair.effects.OPTIONS``) and the input data from ``OperatingPoint``.
    """
    if gp is None:
        gp = importlib.import_module("gearpair")
    from dataclasses import fields

    params_mod = importlib.import_module(gp.__name__ + ".params")
    out: list[dict[str, Any]] = []

    def add(name, typ, causality, variability, unit=None, display_unit=None, lo=None,
            hi=None, start=None, description="", lo_open=False, field=None, codes=None):
        out.append(dict(name=name, type=typ, causality=causality, variability=variability,
                        unit=unit, display_unit=display_unit, min=lo, max=hi, start=start,
                        description=description, lo_open=lo_open, field=field, codes=codes))

    display_in = {"torque": None, "speed": "rpm"}
    for f in fields(params_mod.OperatingPoint):
        m = f.metadata
        add(f.name, "Real", "input", "continuous", m["unit"], display_in.get(f.name),
            m["min"], m["max"], float(f.default), m["doc"] + ", held over each step")
    add("load_speed", "Real", "input", "continuous", "rad/s", "rpm", -params_mod.SPEED_MAX,
        params_mod.SPEED_MAX, 0.0,
        "speed of the load at the far end of the load shaft kr2 (gear 2's sense), held over "
        "each step; used only when the parameter load_speed_input is true")

    for name, typ, unit, dunit, lo, hi, doc in OUTPUTS:
        add(name, typ, "output", "discrete" if typ == "Integer" else "continuous", unit, dunit,
            lo, hi, None, doc)

    for row in params_mod.GearParams.describe():
        is_int = isinstance(row["default"], int) and not isinstance(row["default"], bool)
        doc = row["doc"]
        if row.get("lo_open"):
            doc += f" (must be > {row['min']:g})"
        add(row["name"], "Integer" if is_int else "Real", "parameter", "fixed",
            None if is_int else row["unit"], _PARAM_DISPLAY_UNIT.get(row["unit"]),
            row["min"], row["max"], row["default"], doc, lo_open=bool(row.get("lo_open")))

    effects_mod = importlib.import_module(gp.__name__ + ".effects")
    defaults = effects_mod.Effects().values()
    by_fmu = {m["fmu"]: (name, m) for name, m in effects_mod.OPTIONS.items()}
    unplaced = sorted(set(by_fmu) - set(LATER_VARIABLES))
    if unplaced:
        raise RuntimeError(f"effect parameter(s) {', '.join(unplaced)} have no place in "
                           "LATER_VARIABLES (append them: value references never move)")
    appended = {row[0]: row for row in APPENDED_OUTPUTS}
    for name in LATER_VARIABLES:
        if name in by_fmu:
            field_name, m = by_fmu[name]
            add(name, **_effect_variable(m, defaults[field_name]), field=field_name)
        elif name == "engine":
            engines = tuple(gp.ENGINES)
            add(name, "Integer", "parameter", "fixed", None, None, 0, len(engines) - 1, 0,
                f"{ENGINE_DOC}: {_listing(engines)}", field="engine", codes=engines)
        elif name == "load_speed_input":
            add(name, "Boolean", "parameter", "fixed", start=False,
                description="true: the load shaft kr2/cr2 ends at a load turning at the input "
                "load_speed (a driveline; power flows both ways); false: it ends at the "
                "nominal rotation (the paper)")
        elif name == "rtol":
            add("rtol", "Real", "parameter", "fixed", "1", None, params_mod.RTOL_MIN,
                params_mod.RTOL_MAX, 1e-8, "relative tolerance of the engine's integrator")
        else:
            _, typ, unit, dunit, lo, hi, doc = appended[name]
            add(name, typ, "output", "continuous", unit, dunit, lo, hi, None, doc)
    return out


def _listing(codes) -> str:
    return ", ".join(f"{i} {c}" for i, c in enumerate(codes))


def _effect_variable(m: dict, default) -> dict:
    """`interface` arguments of an effect's FMU parameter from its metadata
    (`gearpair.effects.OPTIONS`): a choice as its code (the index), a number with 0 for None."""
    if m["kind"] == "choice":
        codes = m["fmu_choices"]
        return dict(typ="Integer", causality="parameter", variability="fixed", lo=0,
                    hi=len(codes) - 1, start=codes.index(default),
                    description=f"{m['fmu_doc']}: {_listing(codes)}", codes=codes)
    if m["kind"] == "bool":
        return dict(typ="Boolean", causality="parameter", variability="fixed",
                    start=bool(default), description=m["fmu_doc"])
    return dict(typ="Real", causality="parameter", variability="fixed", unit=m["unit"],
                display_unit=m["display_unit"], lo=0.0 if m["none"] else m["min"],
                hi=m["max"], start=0.0 if default is None else float(default),
                description=m["fmu_doc"])


def choices(spec: list[dict]) -> dict[str, tuple[str, tuple[str, ...]]]:
    """The integer-coded parameters of ``spec`` (`interface`): FMU name -> (what it sets,
    the choices in code order)."""
    return {v["name"]: (v["field"], v["codes"]) for v in spec if v["codes"]}
