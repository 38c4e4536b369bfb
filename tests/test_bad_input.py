"""Bad input: every invalid value gets a clear error that names it, nothing
crashes, and the state is unchanged.

- Core: every `GearParams` field below/above its range, NaN, +-inf and a non-number; every
  `Effects` option; the engine options; NaN/inf/out-of-range inputs and times to
  `FastEngine.advance` (ValueError naming the input; the engine state is untouched and the
  run continues exactly as if the bad call had never been made).
- FMU: every parameter of the model description out of its range (and NaN/inf), a fixed
  parameter changed after initialization, NaN/inf/out-of-range inputs, bad communication
  steps. Each is refused when it is made (the fmi2Set* call or the doStep) with fmi2Error,
  never fmi2Fatal; a combination of parameters at fmi2ExitInitializationMode; the message
  logged names the variable; every output reads the same before and after; the instance
  keeps working and ends bit for bit where an instance that never saw the bad value ends.
- Scenes: unknown keys in every section and CSV inputs whose time does not increase
  strictly (`gearpair.scenes.load_scene` raises ValueError naming the key / the column).
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import fields

import numpy as np
import pytest

pytest.importorskip("numba")

from test_hard_cases import RTOL, STATUS_NAMES, TR, W10, Slave, fmi2OK  # noqa: E402

from gearpair import Effects, GearParams, StiffnessSpec  # noqa: E402
from gearpair.fast import FastEngine  # noqa: E402
from gearpair.results import simulate  # noqa: E402

NAN, INF = float("nan"), float("inf")


def names_it(message: str, name: str) -> bool:
    """The message names ``name`` as a word (``mu`` is not found inside ``module``)."""
    return re.search(rf"(?<![A-Za-z0-9_]){re.escape(name)}(?![A-Za-z0-9_])", message) \
        is not None


# -- core: parameters -----------------------------------------------------------------------------
def _bad_param_values() -> list:
    out = []
    for row in GearParams.describe():
        name, lo, hi = row["name"], row["min"], row["max"]
        is_int = isinstance(row["default"], int)
        below = lo if row["lo_open"] else lo - max(0.5 * abs(lo), 1.0 if is_int else 1e-3)
        above = hi + max(abs(hi), 1.0)
        vals = [("below", int(below) if is_int else below), ("above", int(above) if is_int
                                                             else above),
                ("nan", NAN), ("inf", INF), ("-inf", -INF), ("text", "abc")]
        if is_int:
            vals.append(("fraction", row["default"] + 0.5))
        out += [pytest.param(name, v, id=f"{name}-{k}") for k, v in vals]
    return out


@pytest.mark.parametrize("name, value", _bad_param_values())
def test_every_gear_parameter_refuses_bad_values(name, value):
    with pytest.raises(ValueError) as exc:
        GearParams(**{name: value})
    assert names_it(str(exc.value), name), str(exc.value)


@pytest.mark.parametrize("kw, name", [
    ({"friction": "sticky"}, "friction"), ({"sliding": "both"}, "sliding"),
    ({"stick_tie": "glue"}, "stick_tie"), ({"stiffness": "spline"}, "stiffness"),
    ({"dof": "planar"}, "dof"), ({"v_eps": 0.0}, "v_eps"), ({"v_eps": NAN}, "v_eps"),
    ({"v_eps": 2.0}, "v_eps"), ({"backlash": -1e-4}, "backlash"),
    ({"backlash": NAN}, "backlash"), ({"backlash": INF}, "backlash"),
    ({"backlash": 2e-3}, "backlash"), ({"backlash": 1e-4, "separation": False}, "backlash"),
    ({"separation": "yes"}, "separation"),
])
def test_every_effect_option_refuses_bad_values(kw, name):
    with pytest.raises(ValueError) as exc:
        Effects(**kw)
    assert names_it(str(exc.value), name), str(exc.value)


@pytest.mark.parametrize("table, words", [
    (((0.0, 1e9),), "2 rows"), (((0.0, 1e9), (0.0, 2e9)), "increase"),
    (((0.0, 1e9), (1e-3, NAN)), "finite"), (((0.0, 1e9), (1e-3, -1.0)), ">= 0"),
])
def test_stiffness_table_refuses_bad_rows(table, words):
    with pytest.raises(ValueError, match="stiffness table") as exc:
        StiffnessSpec("table", table=table)
    assert words in str(exc.value)


@pytest.mark.parametrize("kw, name", [
    ({"rtol": 0.0}, "rtol"), ({"rtol": 1.0}, "rtol"), ({"rtol": NAN}, "rtol"),
    ({"n_samples": 0}, "n_samples"),
])
def test_engine_options_refuse_bad_values(kw, name):
    with pytest.raises(ValueError) as exc:
        FastEngine(**kw)
    assert names_it(str(exc.value), name)


def test_simulate_refuses_a_bad_output_interval():
    for dt in (0.0, -1e-4, NAN, INF):
        with pytest.raises(ValueError, match="dt"):
            simulate(dt=dt, t_end=1e-3, engine="fast")


# -- core: inputs ----------------------------------------------------------------------------------
def _same_state(a: dict, b: dict) -> bool:
    if a.keys() != b.keys():
        return False
    for k in a:
        x, y = a[k], b[k]
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y)):
                return False
        elif x != y:
            return False
    return True


BAD_INPUTS = [("torque", NAN), ("torque", INF), ("torque", -INF), ("torque", 2e6),
              ("torque", "abc"), ("speed", NAN), ("speed", INF), ("speed", -INF),
              ("speed", 3e4), ("speed", None)]


@pytest.fixture(scope="module")
def warm_engine():
    """An engine 15 ms into the stick-slip point (a stick is near), and its state."""
    e = FastEngine(rtol=RTOL)
    e.reset(0.0, TR, W10)
    for k in range(1, 16):
        e.advance(k * 1e-3, TR, W10)
    return e.get_state()


@pytest.mark.parametrize("name, value", BAD_INPUTS, ids=[f"{n}-{v}" for n, v in BAD_INPUTS])
def test_engine_refuses_bad_inputs_and_keeps_its_state(warm_engine, name, value):
    e = FastEngine(rtol=RTOL)
    e.set_state(warm_engine)
    before, out_before = e.get_state(), e.outputs()
    args = {"torque": TR, "speed": W10, name: value}
    with pytest.raises(ValueError) as exc:
        e.advance(e.time + 1e-3, args["torque"], args["speed"])
    assert names_it(str(exc.value), name), str(exc.value)
    assert _same_state(e.get_state(), before)
    assert e.outputs() == out_before
    # ... and the run continues exactly as one that never saw the bad call
    twin = FastEngine(rtol=RTOL)
    twin.set_state(warm_engine)
    t = e.time
    for k in range(1, 4):
        assert e.advance(t + k * 1e-3, TR, W10) == twin.advance(t + k * 1e-3, TR, W10)
    assert e.outputs() == twin.outputs()


@pytest.mark.parametrize("dt", [0.0, -1e-3, NAN])
def test_engine_refuses_a_step_that_does_not_go_forward(warm_engine, dt):
    e = FastEngine(rtol=RTOL)
    e.set_state(warm_engine)
    before = e.get_state()
    with pytest.raises(ValueError, match="t_end"):
        e.advance(e.time + dt, TR, W10)
    assert _same_state(e.get_state(), before)


@pytest.mark.parametrize("name", ["torque", "speed"])
def test_engine_reset_refuses_non_finite_inputs(name):
    e = FastEngine(rtol=RTOL)
    with pytest.raises(ValueError) as exc:
        e.reset(0.0, NAN if name == "torque" else TR, NAN if name == "speed" else W10)
    assert names_it(str(exc.value), name)


# -- FMU -------------------------------------------------------------------------------------------
DISCARD, ERROR, FATAL = 2, 3, 4


@pytest.fixture(scope="module")
def unzipdir(fmu_path, md, tmp_path_factory):
    """The FMU extracted once for this module (``md`` skips without fmpy)."""
    from fmpy import extract

    return str(extract(str(fmu_path), unzipdir=str(tmp_path_factory.mktemp("bad_unzip"))))


def _gear_lo_open() -> set[str]:
    return {r["name"] for r in GearParams.describe() if r["lo_open"]}


def _bad_fmu_values(md) -> list[tuple[str, float]]:
    """(parameter, value) pairs that must be refused, from the model description's ranges."""
    lo_open = _gear_lo_open()
    out = []
    for v in md.modelVariables:
        if v.causality != "parameter" or v.type not in ("Real", "Integer"):
            continue
        lo = None if v.min is None else float(v.min)
        hi = None if v.max is None else float(v.max)
        step = 1 if v.type == "Integer" else None
        if lo is not None:
            if v.name in lo_open:
                out.append((v.name, lo))
            out.append((v.name, lo - (step or max(0.5 * abs(lo), 1e-4))))
        if hi is not None:
            out.append((v.name, hi + (step or max(abs(hi), 1e-4))))
        if v.type == "Real":
            out += [(v.name, NAN), (v.name, INF), (v.name, -INF)]
    return out


class Fresh(Slave):
    """A Slave instantiated and set up, not initialized (parameters can still be set)."""

    def __init__(self, md, unzipdir: str, name: str) -> None:
        super(Slave, self).__init__(md, unzipdir, name)  # LoggingSlave's: no initialization
        self.var = {v.name: v for v in md.modelVariables}
        self.outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        self.fmu.setupExperiment(startTime=0.0)


def set_refused(slave: Slave, name: str, value) -> None:
    """fmi2Set* of ``value`` is refused with fmi2Error and a message naming ``name``."""
    from fmpy.fmi1 import FMICallException

    n_msgs = len(slave.messages)
    with pytest.raises(FMICallException) as exc:
        slave.set(name, value)
    assert exc.value.status == ERROR, STATUS_NAMES.get(exc.value.status, exc.value.status)
    new = " | ".join(m for s, m in slave.messages[n_msgs:] if s >= DISCARD)
    assert names_it(new, name), f"the message does not name {name!r}: {new!r}"


@pytest.mark.fmu
def test_fmu_refuses_every_invalid_parameter(md, unzipdir):
    """One instance: each bad value is refused when it is set, with a message naming the
    parameter; none is taken. The refusals are remembered: fmi2ExitInitializationMode is
    refused naming one of them (a master that ignored the fmi2SetReal status must not run
    with a value the user did not get) until each is set to a valid value; then the instance
    initializes and steps normally."""
    from fmpy.fmi1 import FMICallException

    bad = _bad_fmu_values(md)
    names = {n for n, _ in bad}
    gear = {f.name for f in fields(GearParams)}
    assert gear <= names and {"rtol", "v_eps", "friction_law", "stiffness_model"} <= names
    slave = Fresh(md, unzipdir, "bad_parameters")
    try:
        for name, value in bad:
            set_refused(slave, name, value)
        slave.set("torque", TR)
        slave.set("speed", W10)
        slave.fmu.enterInitializationMode()
        n_msgs = len(slave.messages)
        with pytest.raises(FMICallException) as exc:
            slave.fmu.exitInitializationMode()
        assert exc.value.status == ERROR
        said = " | ".join(m for s, m in slave.messages[n_msgs:] if s >= DISCARD)
        assert "refused" in said and any(names_it(said, n) for n in names), said
        for name in sorted(names - {"rtol"}):
            start = slave.var[name].start
            slave.set(name, int(start) if slave.var[name].type == "Integer" else float(start))
        slave.set("rtol", RTOL)
        slave.fmu.exitInitializationMode()
        assert slave.step(0.0, 1e-4) == fmi2OK, slave.errors()
        assert slave.get()["mesh_force"] == pytest.approx(TR / GearParams().rb1, rel=0.5)
    finally:
        slave.close()


@pytest.mark.fmu
def test_fmu_refuses_a_parameter_combination_without_contact(md, unzipdir):
    """Each value in range, together impossible: addendum 0.5 gives a contact ratio < 1.
    Refused at fmi2ExitInitializationMode (fmi2Error), the instance stays in initialization
    mode and initializes once the value is put right."""
    slave = Fresh(md, unzipdir, "no_contact")
    try:
        slave.set("addendum_coef", 0.5)
        slave.fmu.enterInitializationMode()
        from fmpy.fmi1 import FMICallException

        with pytest.raises(FMICallException) as exc:
            slave.fmu.exitInitializationMode()
        assert exc.value.status == ERROR
        assert names_it(slave.errors(), "contact ratio"), slave.errors()
        slave.set("addendum_coef", 1.0)
        slave.fmu.exitInitializationMode()
        assert slave.step(0.0, 1e-4) == fmi2OK, slave.errors()
    finally:
        slave.close()


def _run(slave: Slave, t0: float, n: int, h: float = 1e-3) -> float:
    t = t0
    for _ in range(n):
        assert slave.step(t, h) == fmi2OK, slave.errors()
        t += h
    return t


@pytest.mark.fmu
def test_fmu_refuses_bad_inputs_and_steps_and_keeps_its_state(md, unzipdir):
    """After 15 good steps, every bad input, a changed fixed parameter and every bad step
    size is refused with the state kept; the run then ends bit for bit where an instance that
    never saw them ends."""
    slave = Slave(md, unzipdir, "bad_inputs", {"rtol": RTOL}, inputs=(TR, W10))
    twin = Slave(md, unzipdir, "twin", {"rtol": RTOL}, inputs=(TR, W10))
    try:
        for s in (slave, twin):
            s.set("torque", TR)
            s.set("speed", W10)
        t = _run(slave, 0.0, 15)
        _run(twin, 0.0, 15)
        for name, value in BAD_INPUTS:
            if not isinstance(value, float):
                continue  # a host can only send numbers
            before = slave.get()
            set_refused(slave, name, value)
            assert slave.get() == before
        # a fixed parameter changed after initialization
        set_refused(slave, "mu", 0.05)
        # communication steps that do not go forward, and a wrong communication point
        for tt, h in ((t, 0.0), (t, -1e-3), (t, NAN), (NAN, 1e-3), (t + 1e-3, 1e-3)):
            before = slave.get()
            status = slave.step(tt, h)
            assert status == ERROR, STATUS_NAMES.get(status, status)
            assert slave.get() == before
        t_end = _run(slave, t, 10)
        _run(twin, t, 10)
        assert slave.get() == twin.get()
        assert t_end == pytest.approx(0.025)
    finally:
        slave.close()
        twin.close()


# -- scenes ----------------------------------------------------------------------------------------
GOOD_SCENE = """
t_end = 0.01
[gear]
mu = 0.02
[effects]
friction = "stick_slip"
[inputs]
torque = 3900.0
speed_rpm = 100.0
[solver]
engine = "fast"
[outputs]
interval = 1e-3
"""

UNKNOWN_KEYS = {
    # name: (text to add, the key the error must name)
    "top": ('colour = "red"\n', "colour"),
    "gear": (None, "m3"),
    "effects": (None, "frictoin"),
    "inputs": (None, "torqe"),
    "solver": (None, "engin"),
    "outputs": (None, "intervall"),
}


def _with_key(section: str, key: str) -> str:
    """GOOD_SCENE with ``key = 1.0`` added to ``[section]``."""
    return GOOD_SCENE.replace(f"[{section}]\n", f"[{section}]\n{key} = 1.0\n")


@pytest.mark.parametrize("where", list(UNKNOWN_KEYS))
def test_scene_refuses_unknown_keys_naming_them(tmp_path, where):
    scenes = pytest.importorskip("gearpair.scenes")
    ok = tmp_path / "ok.toml"
    ok.write_text(GOOD_SCENE)
    scenes.load_scene(ok)  # the base scene is valid
    text, key = UNKNOWN_KEYS[where]
    bad = tmp_path / "bad.toml"
    bad.write_text(text + GOOD_SCENE if text else _with_key(where, key))
    with pytest.raises(ValueError) as exc:
        scenes.load_scene(bad)
    assert names_it(str(exc.value), key), str(exc.value)


@pytest.mark.parametrize("where, key", [("inputs.csv", "fil"), ("effects.stiffness", "knd")])
def test_scene_refuses_unknown_keys_in_subtables(tmp_path, where, key):
    scenes = pytest.importorskip("gearpair.scenes")
    (tmp_path / "in.csv").write_text("time,torque\n0,3900\n1,3900\n")
    body = GOOD_SCENE.replace("[inputs]\ntorque = 3900.0\n", "[inputs]\n")
    first = "file = \"in.csv\"\n" if where == "inputs.csv" else "kind = \"constant\"\n"
    body += f"[{where}]\n{first}{key} = 1.0\n"
    path = tmp_path / "bad.toml"
    path.write_text(body)
    with pytest.raises(ValueError) as exc:
        scenes.load_scene(path)
    assert names_it(str(exc.value), key), str(exc.value)


CSV_BAD = {
    "decreasing": "time,torque,speed_rpm\n0,3900,100\n0.02,3900,100\n0.01,3900,100\n",
    "repeated": "time,torque,speed_rpm\n0,3900,100\n0.01,3900,100\n0.01,3000,100\n",
    "nan_time": "time,torque,speed_rpm\n0,3900,100\nnan,3900,100\n",
}


@pytest.mark.parametrize("kind", list(CSV_BAD))
def test_scene_refuses_csv_time_that_does_not_increase(tmp_path, kind):
    scenes = pytest.importorskip("gearpair.scenes")
    (tmp_path / "in.csv").write_text(CSV_BAD[kind])
    body = GOOD_SCENE.replace("torque = 3900.0\nspeed_rpm = 100.0\n", "")
    body += '[inputs.csv]\nfile = "in.csv"\n'
    path = tmp_path / "scene.toml"
    path.write_text(body)
    with pytest.raises(ValueError) as exc:
        scenes.load_scene(path)
    msg = str(exc.value)
    assert names_it(msg, "time") and "in.csv" in msg, msg
    # the same file with the bad row removed loads
    good = "\n".join(CSV_BAD[kind].splitlines()[:2]) + "\n0.03,3900,100\n"
    (tmp_path / "in.csv").write_text(good)
    scenes.load_scene(path)


@pytest.mark.parametrize("line, key", [("torque = nan", "torque"),
                                       ("torque = inf", "torque"),
                                       ("speed_rpm = -inf", "speed_rpm")])
def test_scene_refuses_non_finite_inputs(tmp_path, line, key):
    scenes = pytest.importorskip("gearpair.scenes")
    body = GOOD_SCENE.replace("torque = 3900.0\nspeed_rpm = 100.0\n", "")
    body = body.replace("[inputs]\n", "[inputs]\n" + line + "\n")
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent(body))
    with pytest.raises(ValueError) as exc:
        scenes.load_scene(path)
    assert names_it(str(exc.value), key), str(exc.value)


# -- one range, one wording, everywhere ----------------------------------------------------
def test_one_rtol_range_everywhere(capsys):
    import importlib.util
    from pathlib import Path

    from gearpair.cli import main
    from gearpair.fast import FastEngine
    from gearpair.params import RTOL_MAX, RTOL_MIN
    from gearpair.reference import ReferenceEngine
    from gearpair.scenes import SceneError, parse_scene

    ROOT = Path(__file__).resolve().parents[1]
    assert (RTOL_MIN, RTOL_MAX) == (1e-12, 1e-3)
    for engine in (FastEngine, ReferenceEngine):
        for bad in (1e-13, 1e-2):
            with pytest.raises(ValueError, match=r"rtol = .* allowed \[1e-12, 0.001\]$"):
                engine(rtol=bad)
    with pytest.raises(SceneError, match=r"rtol = 0.01 is out of range; allowed "
                                         r"\[1e-12, 0.001\]$"):
        parse_scene({"solver": {"rtol": 1e-2}})
    assert main(["simulate", "--rtol", "1e-13", "--t-end", "0.001"]) == 2
    assert "allowed [1e-12, 0.001]" in capsys.readouterr().err
    spec = importlib.util.spec_from_file_location("_gp_slave", ROOT / "fmu_src" / "GearPair.py")
    pytest.importorskip("pythonfmu")
    slave = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(slave)
    rtol = next(v for v in slave.interface() if v["name"] == "rtol")
    assert (rtol["min"], rtol["max"]) == (RTOL_MIN, RTOL_MAX)


def test_dimensionless_units_are_not_printed_as_1():
    with pytest.raises(ValueError) as exc:
        GearParams(mu=2.0)
    assert str(exc.value) == "mu = 2.0 is out of range; allowed [0, 1]"
    with pytest.raises(ValueError) as exc:
        GearParams(m1=-1.0)
    assert str(exc.value).endswith("allowed (0, 100000] kg")
