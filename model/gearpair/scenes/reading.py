"""Reading a scene file: TOML into a validated `Scene`.

Everything inside is SI. Keys whose unit is not SI say so in their name (``speed_rpm``,
``pressure_angle_deg``). Every error names the key (``[gear] m1 = -3 is out of range; ...``),
and relative file names are resolved against the scene file's folder.
"""

from __future__ import annotations

import csv
import math
import sys
from dataclasses import fields
from pathlib import Path
from typing import Any

from ..effects import OPTIONS, Effects, StiffnessSpec
from ..equations import check_friction_coefficients
from ..geometry import BORE_RATIO_MAX
from ..inputs import Constant, Ramp, Schedule, Series, Step
from ..params import RPM, RTOL_MAX, RTOL_MIN, GearParams, OperatingPoint, check_range, unit_name
from .errors import SceneError, SceneWarning
from .types import (
    ENGINES,
    OUTPUT_NAMES,
    STEP_MAX,
    STEP_MIN,
    T_END_MAX,
    Inputs,
    OutputSpec,
    Scene,
    Solver,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser as the backport
    import tomli as tomllib

# Inputs: scene key -> (signal, unit shown in messages, factor to SI).
_SIGNALS = {"torque": ("torque", "N.m", 1.0), "speed": ("speed", "rad/s", 1.0),
            "speed_rpm": ("speed", "r/min", RPM)}
_OP = {f.name: f.metadata for f in fields(OperatingPoint)}  # input ranges (SI)


def _show(v: Any) -> str:
    """A value as it would be written in TOML."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace('"', '\\"') + '"'
    if isinstance(v, dict):
        return "{...}"
    if isinstance(v, list):
        return "[...]"
    return repr(v)


def _toml_type(v: Any) -> str:
    for t, name in ((bool, "boolean"), (int, "integer"), (float, "float"), (str, "string"),
                    (dict, "table"), (list, "array")):
        if isinstance(v, t):
            return name
    return type(v).__name__


def _key(where: str, key: str) -> str:
    return f"[{where}] {key}" if where else key


def _keys(where: str, d: dict, allowed: tuple[str, ...] | list[str]) -> None:
    unknown = [k for k in d if k not in allowed]
    if unknown:
        place = f"[{where}]" if where else "the top level"
        raise SceneError(f"unknown key {unknown[0]!r} in {place}; allowed: {', '.join(allowed)}")


def _table(where: str, key: str, v: Any) -> dict:
    if not isinstance(v, dict):
        raise SceneError(f"{_key(where, key)} = {_show(v)}: expected a table, got {_toml_type(v)}")
    return v


def _num(where: str, key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise SceneError(f"{_key(where, key)} = {_show(v)}: expected a number, "
                         f"got {_toml_type(v)}")
    if not math.isfinite(v):
        raise SceneError(f"{_key(where, key)} = {_show(v)}: must be finite")
    return float(v)


def _int(where: str, key: str, v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise SceneError(f"{_key(where, key)} = {_show(v)}: expected an integer, "
                         f"got {_toml_type(v)}")
    return int(v)


def _str(where: str, key: str, v: Any) -> str:
    if not isinstance(v, str):
        raise SceneError(f"{_key(where, key)} = {_show(v)}: expected a string, "
                         f"got {_toml_type(v)}")
    return v


def _bool(where: str, key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise SceneError(f"{_key(where, key)} = {_show(v)}: expected true or false, "
                         f"got {_toml_type(v)}")
    return v


def _range(where: str, key: str, x: float, lo: float | None, hi: float | None, unit: str,
           lo_open: bool = False) -> float:
    """Check ``x`` against a range; the message names the key and what is allowed."""
    try:
        check_range(key, x, {"min": lo, "max": hi, "unit": unit, "lo_open": lo_open})
    except ValueError as exc:
        raise SceneError(f"[{where}] {exc}" if where else str(exc)) from None
    return x


def _prefixed(where: str, key: str, v: Any, exc: Exception) -> SceneError:
    """Put the key path in front of a validation message from GearParams or Effects."""
    msg = str(exc)
    if msg.startswith(key):
        return SceneError(f"[{where}] {msg}")
    return SceneError(f"[{where}] {key} = {_show(v)}: {msg}")


def _resolve(base: Path, where: str, key: str, v: Any) -> Path:
    p = Path(_str(where, key, v)).expanduser()
    p = p if p.is_absolute() else base / p
    if not p.is_file():
        raise SceneError(f"{_key(where, key)} = {_show(v)}: no such file ({p})")
    return p


_DERIVED = {"bore_ratio": ("m1", "J1", "m2", "J2"), "first_mode_hz": ("kr2",)}


def _derivation(d: dict) -> dict[str, Any]:
    """``[gear] bore_ratio`` and ``first_mode_hz``: what `gearpair.modal.derive_params`
    derives, checked against the fields it would overwrite."""
    where, out = "gear", {}
    for key, derived in _DERIVED.items():
        if key not in d:
            continue
        given = [k for k in derived if k in d]
        if given:
            raise SceneError(f"[gear] give {', '.join(given)} or {key} (which derives "
                             f"{', '.join(derived)}), not both")
        v = d[key]
        if key == "bore_ratio" and isinstance(v, list):
            if len(v) != 2:
                raise SceneError(f"[gear] bore_ratio = {_show(v)}: one number for both gears "
                                 "or [gear 1, gear 2]")
            vals = tuple(_num(where, f"bore_ratio[{i}]", x) for i, x in enumerate(v))
        else:
            vals = (_num(where, key, v),)
        for x in vals:
            if key == "bore_ratio":
                _range(where, key, x, 0.0, BORE_RATIO_MAX, "(bore diameter over pitch diameter)")
            else:
                _range(where, key, x, 0.0, 1e5, "Hz", lo_open=True)
        out[key] = vals if len(vals) == 2 else vals[0]
    return out


def _derive(params: GearParams, derive: dict[str, Any], effects: Effects) -> GearParams:
    if not derive:
        return params
    from ..modal import derive_params

    try:
        return derive_params(params, effects=effects, **derive)
    except ValueError as exc:
        raise SceneError(f"[gear] {exc}") from None


def _gear(d: dict) -> tuple[GearParams, dict[str, Any]]:
    """``[gear]``: the `GearParams` as written, and what is to be derived from them."""
    where = "gear"
    meta = {f.name: f for f in fields(GearParams)}
    _keys(where, d, [*meta, "pressure_angle_deg", *_DERIVED])
    if "pressure_angle" in d and "pressure_angle_deg" in d:
        raise SceneError("[gear] give pressure_angle (rad) or pressure_angle_deg, not both")
    derive = _derivation(d)
    kw: dict[str, Any] = {}
    for key, v in d.items():
        if key in _DERIVED:
            continue
        if key == "pressure_angle_deg":
            m = meta["pressure_angle"].metadata
            deg = _range(where, key, _num(where, key, v), math.degrees(m["min"]),
                         math.degrees(m["max"]), "deg")
            kw["pressure_angle"] = math.radians(deg)
        elif isinstance(meta[key].default, int):
            kw[key] = _int(where, key, v)
        else:
            kw[key] = _num(where, key, v)
    try:
        return GearParams(**kw), derive
    except ValueError as exc:  # GearParams' messages start with the field name
        raise SceneError(f"[{where}] {exc}") from None


_EFFECT_KEYS = tuple(OPTIONS)  # every Effects field is a key (`gearpair.effects.OPTIONS`)


def _stiffness(d: Any, base: Path, params: GearParams) -> StiffnessSpec:
    where = "effects.stiffness"
    if isinstance(d, str):
        if d == "table":
            raise SceneError('[effects] stiffness = "table" needs a file: write [effects.stiffness]'
                             ' with kind = "table" and file = "table.csv"')
        try:
            return StiffnessSpec(kind=d)
        except ValueError as exc:
            raise _prefixed("effects", "stiffness", d, exc) from None
    d = _table("effects", "stiffness", d)
    _keys(where, d, ("kind", "file", "scale_to_mean"))
    kind = _str(where, "kind", d.get("kind", "potential_energy"))
    scale = _bool(where, "scale_to_mean", d.get("scale_to_mean", True))
    table = None
    if kind == "table":
        if "file" not in d:
            raise SceneError('[effects.stiffness] kind = "table" needs file = "table.csv" '
                             "(columns position_m or angle_rad, stiffness_n_per_m)")
        path = _resolve(base, where, "file", d["file"])
        from ..stiffness import read_table

        try:
            table = read_table(path, params)
        except ValueError as exc:
            raise SceneError(f"[{where}] file = {_show(d['file'])}: {exc}") from None
    elif "file" in d:
        raise SceneError(f'[{where}] file is only used with kind = "table" (kind = "{kind}")')
    try:
        return StiffnessSpec(kind=kind, table=table, scale_to_mean=scale)
    except ValueError as exc:
        key = "kind" if kind != "table" else "file"
        raise _prefixed(where, key, d.get(key), exc) from None


def _effects(d: dict, base: Path, params: GearParams) -> Effects:
    where = "effects"
    _keys(where, d, _EFFECT_KEYS)
    kw: dict[str, Any] = {}
    for key, v in d.items():
        if key == "stiffness":
            kw[key] = _stiffness(v, base, params)
        else:
            read = {"bool": _bool, "number": _num, "choice": _str}[OPTIONS[key]["kind"]]
            kw[key] = read(where, key, v)
    try:
        fx = Effects(**kw)
        check_friction_coefficients(params, fx)  # mu_static against the gear's mu, at load
        return fx
    except ValueError as exc:  # Effects' messages start with the field (or fields) concerned
        raise SceneError(f"[{where}] {exc}") from None


def _value(where: str, signal_key: str, key: str, v: Any) -> float:
    """An input value written under ``key`` in the unit of the input ``signal_key`` (torque,
    speed or speed_rpm), range-checked and converted to SI."""
    signal, unit, factor = _SIGNALS[signal_key]
    m = _OP[signal]
    x = _num(where, key, v)
    return _range(where, key, x, m["min"] / factor, m["max"] / factor, unit) * factor


def _time_value(where: str, key: str, v: Any) -> float:
    return _range(where, key, _num(where, key, v), 0.0, T_END_MAX, "s")


_KINDS = {"constant": ("value",), "ramp": ("from", "to", "t0", "t1"),
          "step": ("before", "after", "at")}


def _schedule(key: str, v: Any) -> Schedule:
    """The input written under ``[inputs] key``: a number (constant) or a table with kind."""
    if not isinstance(v, dict):
        return Constant(_value("inputs", key, key, v))
    where = f"inputs.{key}"
    if "kind" not in v:
        raise SceneError(f"[{where}] needs kind = one of {', '.join(_KINDS)} "
                         "(or write a number for a constant)")
    kind = _str(where, "kind", v["kind"])
    if kind not in _KINDS:
        raise SceneError(f"[{where}] kind = {_show(kind)} is not allowed; choose one of "
                         + ", ".join(_KINDS) + " (a CSV series goes in [inputs.csv])")
    allowed = ("kind", *_KINDS[kind])
    _keys(where, v, allowed)
    missing = [k for k in allowed if k not in v]
    if missing:
        raise SceneError(f'[{where}] kind = "{kind}" needs {", ".join(missing)}')

    def val(k: str) -> float:
        return _value(where, key, k, v[k])

    if kind == "constant":
        return Constant(val("value"))
    if kind == "ramp":
        t0, t1 = _time_value(where, "t0", v["t0"]), _time_value(where, "t1", v["t1"])
        if not t1 > t0:
            raise SceneError(f"[{where}] t1 = {_show(v['t1'])} must be after "
                             f"t0 = {_show(v['t0'])}")
        return Ramp(val("from"), val("to"), t0, t1)
    return Step(val("before"), val("after"), _time_value(where, "at", v["at"]))


def _csv_series(d: Any, base: Path) -> dict[str, Series]:
    """``[inputs.csv]``: the inputs named in ``columns`` from one CSV file, by scene key."""
    where = "inputs.csv"
    d = _table("inputs", "csv", d)
    _keys(where, d, ("file", "columns"))
    if "file" not in d:
        raise SceneError(f"[{where}] needs file = \"inputs.csv\"")
    path = _resolve(base, where, "file", d["file"])
    with path.open(newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    if len(rows) < 2:
        raise SceneError(f"[{where}] file {path}: needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    if "columns" in d:
        cols = _table(where, "columns", d["columns"])
        _keys(f"{where}.columns", cols, ("time", *_SIGNALS))
        cols = {k: _str(f"{where}.columns", k, c) for k, c in cols.items()}
        cols.setdefault("time", "time")
    else:  # columns named like the scene keys
        cols = {k: k for k in ("time", *_SIGNALS) if k in header}
        for h in header:
            # a misspelt input would silently keep its default; gearpair's own output
            # columns (a CSV written by --out) are known and not inputs
            if h not in cols and h not in OUTPUT_NAMES:
                import difflib
                import warnings

                near = difflib.get_close_matches(h, ["time", *_SIGNALS], n=1, cutoff=0.0)
                warnings.warn(SceneWarning(
                    f"[{where}] file {path}: column {h!r} is not an input and is ignored "
                    f"(closest input name: {near[0]!r}; inputs: time, "
                    f"{', '.join(_SIGNALS)}; map the file explicitly with columns = {{...}} "
                    "to silence this)"), stacklevel=2)
    if "time" not in cols or cols["time"] not in header:
        raise SceneError(f"[{where}] file {path}: no time column {cols.get('time', 'time')!r}; "
                         f"columns: {', '.join(header)}")
    signals = [k for k in cols if k != "time"]
    if not signals:
        raise SceneError(f"[{where}] file {path}: no input column; name them in columns = "
                         "{ torque = \"...\", speed_rpm = \"...\" } (or speed, rad/s)")
    for k in signals:
        if cols[k] not in header:
            raise SceneError(f"[{where}.columns] {k} = {_show(cols[k])}: no such column in "
                             f"{path}; columns: {', '.join(header)}")
    idx = {k: header.index(c) for k, c in cols.items()}
    values: dict[str, list[float]] = {k: [] for k in cols}
    for line, row in enumerate(rows[1:], start=2):
        for k, i in idx.items():
            try:
                x = float(row[i])
            except (ValueError, IndexError):
                raise SceneError(f"[{where}] file {path}, row {line}, column {cols[k]!r}: "
                                 "a number expected") from None
            if not math.isfinite(x):
                raise SceneError(f"[{where}] file {path}, row {line}, column {cols[k]!r}: "
                                 f"{row[i]!r} is not finite")
            values[k].append(x)
        t = values["time"]
        if len(t) > 1 and not t[-1] > t[-2]:
            raise SceneError(f"[{where}] file {path}, row {line}: time {t[-1]:g} s does not "
                             f"increase (previous row {t[-2]:g} s); time must increase strictly")
    out = {}
    for k in signals:
        signal, unit, factor = _SIGNALS[k]
        lo, hi = _OP[signal]["min"] / factor, _OP[signal]["max"] / factor
        bad = [i for i, x in enumerate(values[k]) if not lo <= x <= hi]
        if bad:
            raise SceneError(f"[{where}] file {path}, row {bad[0] + 2}, column {cols[k]!r}: "
                             f"{k} = {values[k][bad[0]]:g} is out of range; allowed "
                             f"[{lo:g}, {hi:g}] {unit_name(unit)}".rstrip())
        out[k] = Series(tuple(values["time"]), tuple(x * factor for x in values[k]),
                        f"{path.name}:{cols[k]}")
    return out


def _inputs(d: dict, base: Path) -> Inputs:
    where = "inputs"
    _keys(where, d, (*_SIGNALS, "csv"))
    given: dict[str, Schedule] = {}
    if "csv" in d:
        given.update(_csv_series(d["csv"], base))
    for key, v in d.items():
        if key == "csv":
            continue
        if key in given:
            raise SceneError(f"[inputs] {key} is given twice: as a key and as a column of "
                             "[inputs.csv]")
        given[key] = _schedule(key, v)
    if "speed" in given and "speed_rpm" in given:
        raise SceneError("[inputs] give speed (rad/s) or speed_rpm (r/min), not both")
    op = Inputs()
    return Inputs(torque=given.get("torque", op.torque),
                  speed=given.get("speed", given.get("speed_rpm", op.speed)))


def _solver(d: dict) -> Solver:
    where = "solver"
    _keys(where, d, ("engine", "rtol", "step", "static_start"))
    kw: dict[str, Any] = {}
    if "engine" in d:
        kw["engine"] = _str(where, "engine", d["engine"])
        if kw["engine"] not in ENGINES:
            raise SceneError(f"[solver] engine = {_show(d['engine'])} is not allowed; choose "
                             "one of " + ", ".join(ENGINES))
    if "rtol" in d:
        kw["rtol"] = _range(where, "rtol", _num(where, "rtol", d["rtol"]), RTOL_MIN, RTOL_MAX,
                            "")
    if "step" in d:
        kw["step"] = _range(where, "step", _num(where, "step", d["step"]), STEP_MIN, STEP_MAX,
                            "s")
    if "static_start" in d:
        kw["static_start"] = _bool(where, "static_start", d["static_start"])
    return Solver(**kw)


def _outputs(d: dict, t_end: float) -> OutputSpec:
    where = "outputs"
    _keys(where, d, ("names", "interval", "t_from"))
    kw: dict[str, Any] = {}
    if "names" in d:
        names = d["names"]
        if not isinstance(names, list):
            raise SceneError(f"[outputs] names = {_show(names)}: expected an array of strings, "
                             f"got {_toml_type(names)}")
        for i, n in enumerate(names):
            _str(where, f"names[{i}]", n)
            if n not in OUTPUT_NAMES and n != "time":
                raise SceneError(f"[outputs] names[{i}] = {_show(n)} is not an output; "
                                 f"choose from {', '.join(OUTPUT_NAMES)}")
        kw["names"] = tuple(dict.fromkeys(n for n in names if n != "time"))
    if "interval" in d:
        kw["interval"] = _range(where, "interval", _num(where, "interval", d["interval"]),
                                STEP_MIN, STEP_MAX, "s")
    if "t_from" in d:
        t = _num(where, "t_from", d["t_from"])
        if not 0.0 <= t < t_end:
            raise SceneError(f"[outputs] t_from = {_show(d['t_from'])} is out of range; allowed "
                             f"[0, t_end) = [0, {t_end:g}) s")
        kw["t_from"] = t
    return OutputSpec(**kw)


_TOP = ("name", "description", "t_end", "gear", "effects", "inputs", "solver", "outputs")


def parse_scene(doc: dict, base: str | Path = ".", name: str = "scene",
                path: Path | None = None) -> Scene:
    """Validate a scene given as a dict (parsed TOML); ``base`` resolves relative files."""
    base = Path(base)
    _keys("", doc, _TOP)
    sec = {k: _table("", k, doc.get(k, {})) for k in ("gear", "effects", "inputs", "solver",
                                                        "outputs")}
    t_end = _range("", "t_end", _num("", "t_end", doc.get("t_end", 0.2)), 0.0, T_END_MAX, "s",
                   lo_open=True)
    params, derive = _gear(sec["gear"])
    effects = _effects(sec["effects"], base, params)
    params = _derive(params, derive, effects)
    inputs = _inputs(sec["inputs"], base)
    solver = _solver(sec["solver"])
    outputs = _outputs(sec["outputs"], t_end)
    step = outputs.interval if solver.step is None else solver.step
    k = outputs.interval / step
    if step > outputs.interval * (1 + 1e-9) or abs(k - round(k)) > 1e-6 * k:
        raise SceneError(f"[solver] step = {step:g} s must divide [outputs] interval = "
                         f"{outputs.interval:g} s a whole number of times")
    if t_end < step * (1 - 1e-9):
        raise SceneError(f"t_end = {t_end:g} s is shorter than one step ({step:g} s)")
    return Scene(
        name=_str("", "name", doc.get("name", name)), params=params, effects=effects,
        inputs=inputs, solver=solver, outputs=outputs, t_end=t_end,
        description=_str("", "description", doc.get("description", "")), path=path)


def load_scene(path: str | Path) -> Scene:
    """Read and validate a TOML scene file.

    Raises
    ------
    SceneError
        (a ``ValueError``) naming the file and the key: unknown keys list the allowed ones,
        wrong types say the expected type, out-of-range values say the allowed range.
    """
    path = Path(path)
    try:
        with path.open("rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise SceneError(f"scene file {path} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    try:
        return parse_scene(doc, path.resolve().parent, path.stem, path)
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None
