"""Scene files (gearpair.scenes): reading, validation messages, schedules, the shipped scenes,
the FMU as an engine and the `gearpair simulate SCENE.toml` command line."""

from __future__ import annotations

import json
import math
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gearpair import GearParams
from gearpair.cli import main
from gearpair.inputs import Constant, Ramp, Series, Step
from gearpair.params import RPM
from gearpair.scenes import (
    OUTPUT_NAMES,
    OutputSpec,
    Scene,
    SceneError,
    Solver,
    load_scene,
)

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "examples" / "scenes").glob("*.toml"))
RB1 = GearParams().rb1


def write(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    p = tmp_path / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(textwrap.dedent(text))
    return p


def run_or_skip(scene: Scene, engine: str = "fast", **kw):
    """Run; skip (with the engine's reason) scenes whose effects the engine does not support
    yet, so they start running as soon as it does."""
    try:
        return scene.run(engine, **kw)
    except ValueError as exc:
        fx = scene.effects
        if (fx.backlash is not None or fx.dof != "full") and "not supported" in str(exc):
            pytest.skip(f"{scene.name}: engine {engine} does not support backlash/torsional "
                        f"yet ({exc})")
        raise


# -- reading --------------------------------------------------------------------------------------
def test_round_trip_lands_in_params_effects_inputs(tmp_path):
    (tmp_path / "sub" / "tables").mkdir(parents=True)
    (tmp_path / "sub" / "tables" / "k.csv").write_text(
        "position_m,stiffness_n_per_m\n0.0,1.0e9\n0.01,2.0e9\n0.03,1.5e9\n")
    path = write(tmp_path, """
        description = "round trip"
        t_end = 0.05
        [gear]
        m1 = 20.5
        z1 = 31
        pressure_angle_deg = 22.5
        kr2 = 3.0e6
        mu = 0.05
        [effects]
        separation = false
        friction = "regularized"
        v_eps = 2e-4
        sliding = "full"
        stick_tie = "paper"
        [effects.stiffness]
        kind = "table"
        file = "tables/k.csv"
        scale_to_mean = false
        [inputs]
        speed_rpm = 250.0
        [inputs.torque]
        kind = "step"
        before = 1000.0
        after = -500.0
        at = 0.01
        [solver]
        engine = "reference"
        rtol = 1e-9
        step = 5e-5
        static_start = false
        [outputs]
        names = ["dte", "torque"]
        interval = 2e-4
        t_from = 0.02
        """, "sub/my_scene.toml")
    s = load_scene(path)
    assert s.name == "my_scene" and s.description == "round trip" and s.path == path
    assert s.t_end == 0.05
    p = s.params
    assert (p.m1, p.z1, p.kr2, p.mu) == (20.5, 31, 3.0e6, 0.05)
    assert p.pressure_angle == pytest.approx(math.radians(22.5), rel=1e-15)
    assert p.m2 == GearParams().m2  # untouched fields keep Table 1
    fx = s.effects
    assert (fx.separation, fx.friction, fx.v_eps, fx.sliding, fx.stick_tie) == \
        (False, "regularized", 2e-4, "full", "paper")
    # the table file is resolved against the scene's folder, not the working directory
    assert fx.stiffness.kind == "table" and fx.stiffness.scale_to_mean is False
    assert fx.stiffness.table == ((0.0, 1.0e9), (0.01, 2.0e9), (0.03, 1.5e9))
    assert s.inputs.speed == Constant(250.0 * RPM)
    assert s.inputs.torque == Step(1000.0, -500.0, 0.01)
    assert (s.solver.engine, s.solver.rtol, s.solver.step, s.solver.static_start) == \
        ("reference", 1e-9, 5e-5, False)
    assert s.outputs.names == ("dte", "torque") and s.outputs.interval == 2e-4
    assert (s.t_from, s.every) == (0.02, 4)


def test_defaults_are_the_operating_point(tmp_path):
    s = load_scene(write(tmp_path, "t_end = 0.01\n"))
    assert s.params == GearParams()
    assert s.inputs.torque(0.0) == 3900.0
    assert s.inputs.speed(0.0) == pytest.approx(100 * RPM, rel=1e-15)
    assert s.solver.engine == "fast" and s.outputs.names == OUTPUT_NAMES
    assert s.t_from == 0.005  # half of t_end


def test_schedules_between_and_at_their_breakpoints():
    r = Ramp(1000.0, 3000.0, 0.002, 0.006)
    assert [r(t) for t in (0.0, 0.002, 0.003, 0.005, 0.006, 1.0)] == \
        pytest.approx([1000.0, 1000.0, 1500.0, 2500.0, 3000.0, 3000.0], rel=1e-12)
    st = Step(1.0, 2.0, 0.004)
    assert st(0.0039) == 1.0 and st(0.004) == 2.0
    assert st(5e-4 * 8) == 2.0  # a grid point that should sit on `at` (round-off tolerated)
    se = Series((0.0, 0.1, 0.3), (0.0, 10.0, 30.0))
    assert [se(t) for t in (-1.0, 0.05, 0.2, 0.3, 5.0)] == pytest.approx([0, 5, 20, 30, 30])


def test_ramp_and_step_reach_the_engine_at_sample_times(tmp_path):
    """Inputs are sampled at the start of each communication step (5e-4 s) and held; each
    output row (every 1e-3 s) holds the values of its last step."""
    s = load_scene(write(tmp_path, """
        t_end = 0.01
        [effects]
        stiffness = "constant"
        friction = "off"
        [inputs.torque]
        kind = "ramp"
        from = 1000.0
        to = 3000.0
        t0 = 0.002
        t1 = 0.006
        [inputs.speed_rpm]
        kind = "step"
        before = 100.0
        after = 200.0
        at = 0.004
        [solver]
        step = 5e-4
        [outputs]
        interval = 1e-3
        """))
    tr = s.run("fast")
    t = tr.time
    np.testing.assert_allclose(t, np.linspace(0.0, 0.01, 11), atol=1e-15)
    # row at t holds the value sampled at t - 5e-4 (row 0: the value at 0)
    expect_T = [1000, 1000, 1000, 1250, 1750, 2250, 2750, 3000, 3000, 3000, 3000]
    np.testing.assert_allclose(tr["torque"], expect_T, rtol=1e-12)
    expect_rpm = [100, 100, 100, 100, 100, 200, 200, 200, 200, 200, 200]
    np.testing.assert_allclose(tr["speed"] / RPM, expect_rpm, rtol=1e-12)
    # the engine saw them: static start under 1000 N.m (constant stiffness: exactly T/rb1),
    # and the mesh force follows the torque up to 3000 N.m (still ringing at the 32 Hz mode)
    assert tr["mesh_force"][0] == pytest.approx(1000.0 / RB1, rel=1e-6)
    assert tr["mesh_force"][-1] == pytest.approx(3000.0 / RB1, rel=0.3)


def test_csv_inputs_resolve_relative_to_scene_and_interpolate(tmp_path):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "drive.csv").write_text(
        "# comment\nt_s,T,n\n0.0,1000,0\n0.01,2000,600\n")
    s = load_scene(write(tmp_path, """
        t_end = 0.01
        [inputs.csv]
        file = "in/drive.csv"
        columns = { time = "t_s", torque = "T", speed_rpm = "n" }
        """))
    assert isinstance(s.inputs.torque, Series)
    assert s.inputs.torque(0.005) == pytest.approx(1500.0)
    assert s.inputs.speed(0.0025) == pytest.approx(150.0 * RPM)


# -- validation: every message names the file and the key --------------------------------------
BAD = {
    # unknown keys, at each level: the message lists what is allowed
    "unknown_top": ("colour = 1", ["unknown key 'colour'", "top level", "t_end"]),
    "unknown_gear": ("[gear]\nmass1 = 3", ["unknown key 'mass1'", "[gear]", "m1, m2"]),
    "unknown_effects": ('[effects]\nfrictoin = "off"', ["'frictoin'", "[effects]",
                                                       "friction"]),
    "unknown_stiffness": ('[effects.stiffness]\nkind = "constant"\nscale = true',
                          ["'scale'", "[effects.stiffness]", "scale_to_mean"]),
    "unknown_inputs": ("[inputs]\nrpm = 100", ["'rpm'", "[inputs]", "speed_rpm"]),
    "unknown_schedule": ('[inputs.torque]\nkind = "ramp"\nfrom = 1\nto = 2\nt0 = 0\nt1 = 1\n'
                         "at = 3", ["'at'", "[inputs.torque]", "t1"]),
    "unknown_csv": ('[inputs.csv]\nfile = "x.csv"\ndelimiter = ";"',
                    ["'delimiter'", "[inputs.csv]", "columns"]),
    "unknown_solver": ("[solver]\ntolerance = 1e-8", ["'tolerance'", "[solver]", "rtol"]),
    "unknown_outputs": ("[outputs]\nevery = 2", ["'every'", "[outputs]", "interval"]),
    # wrong types: the expected type
    "type_int": ("[gear]\nz1 = 33.5", ["[gear] z1 = 33.5", "expected an integer"]),
    "type_number": ('[gear]\nm1 = "17"', ['[gear] m1 = "17"', "expected a number",
                                          "string"]),
    "type_bool": ('[effects]\nseparation = "yes"', ["[effects] separation",
                                                    "expected true or false"]),
    "type_string": ("[effects]\nfriction = 3", ["[effects] friction", "expected a string"]),
    "type_rtol": ('[solver]\nrtol = "1e-8"', ["[solver] rtol", "expected a number"]),
    "type_t_end": ("t_end = true", ["t_end = true", "expected a number", "boolean"]),
    "type_names": ('[outputs]\nnames = "dte"', ["[outputs] names", "expected an array"]),
    "type_table": ("gear = 3", ["gear = 3", "expected a table"]),
    "type_schedule": ("[inputs.torque]\nfrom = 1", ["[inputs.torque]", "needs kind"]),
    # out of range: the allowed range (GearParams' and Effects' own checks, with the path)
    "range_gear": ("[gear]\nm1 = -3", ["[gear] m1 = -3.0 is out of range", "(0, 100000] kg"]),
    "range_deg": ("[gear]\npressure_angle_deg = 50", ["[gear] pressure_angle_deg = 50",
                                                      "[10, 35] deg"]),
    "range_choice": ('[effects]\nfriction = "coulomb"', ["[effects] friction", "stick_slip"]),
    "range_v_eps": ("[effects]\nv_eps = 0.0", ["[effects] v_eps", "[1e-09, 1] m/s"]),
    "range_backlash": ("[effects]\nbacklash = 0.01", ["[effects] backlash", "(0, 0.001] m"]),
    "range_speed": ("[inputs]\nspeed_rpm = 1e6", ["[inputs] speed_rpm = 1000000.0",
                                                 "r/min"]),
    "range_ramp_value": ('[inputs.torque]\nkind = "ramp"\nfrom = 0\nto = 2e6\nt0 = 0\nt1 = 1',
                         ["[inputs.torque] to = 2000000.0", "[-1e+06, 1e+06] N.m"]),
    "range_ramp_times": ('[inputs.torque]\nkind = "ramp"\nfrom = 0\nto = 1\nt0 = 0.2\nt1 = 0.1',
                         ["[inputs.torque] t1 = 0.1 must be after t0 = 0.2"]),
    "range_rtol": ("[solver]\nrtol = 0.1", ["[solver] rtol", "[1e-12, 0.001]"]),
    "range_engine": ('[solver]\nengine = "rk4"', ["[solver] engine", "fast, reference, fmu"]),
    "range_t_from": ("t_end = 0.2\n[outputs]\nt_from = 5.0", ["[outputs] t_from",
                                                              "[0, 0.2) s"]),
    "range_name": ('[outputs]\nnames = ["dte", "torq"]', ['names[1] = "torq"',
                                                         "mesh_force"]),
    "range_t_end": ("t_end = -1.0", ["t_end = -1.0 is out of range", "(0, 3600] s"]),
    "step_divides": ("[solver]\nstep = 3e-5\n[outputs]\ninterval = 1e-4",
                     ["[solver] step", "[outputs] interval", "whole number"]),
    "both_speeds": ("[inputs]\nspeed = 10.0\nspeed_rpm = 100.0", ["speed_rpm", "not both"]),
    "table_needs_file": ('[effects]\nstiffness = "table"', ['[effects] stiffness = "table"',
                                                           "file"]),
    # files
    "missing_csv": ('[inputs.csv]\nfile = "nowhere.csv"', ['[inputs.csv] file = "nowhere.csv"',
                                                          "no such file"]),
    "missing_table": ('[effects.stiffness]\nkind = "table"\nfile = "k.csv"',
                      ['[effects.stiffness] file = "k.csv"', "no such file"]),
    "bad_toml": ("t_end = = 1", ["not valid TOML"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_invalid_scene_names_the_key(tmp_path, case):
    text, expected = BAD[case]
    path = write(tmp_path, text + "\n")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)), msg
    for part in expected:
        assert part in msg, (part, msg)


def _csv_scene(tmp_path, rows: str, columns: str = "") -> Path:
    (tmp_path / "in.csv").write_text(rows)
    return write(tmp_path, f'[inputs.csv]\nfile = "in.csv"\n{columns}\n')


def test_csv_time_must_increase_strictly(tmp_path):
    path = _csv_scene(tmp_path, "time,torque\n0.0,1\n0.1,2\n0.1,3\n0.2,4\n")
    with pytest.raises(SceneError, match=r"in\.csv, row 4: time 0\.1 s does not increase"):
        load_scene(path)


def test_csv_column_errors_name_file_row_and_column(tmp_path):
    path = _csv_scene(tmp_path, "time,torque\n0.0,1\n0.1,abc\n")
    with pytest.raises(SceneError, match=r"in\.csv, row 3, column 'torque': a number"):
        load_scene(path)
    path = _csv_scene(tmp_path, "time,T\n0.0,1\n", 'columns = { torque = "Torque" }')
    with pytest.raises(SceneError, match=r"\[inputs\.csv\.columns\] torque = \"Torque\": no "
                       r"such column .* columns: time, T"):
        load_scene(path)
    path = _csv_scene(tmp_path, "time,speed_rpm\n0.0,1e6\n")
    with pytest.raises(SceneError, match=r"row 2, column 'speed_rpm': speed_rpm = 1e\+06 is "
                       r"out of range"):
        load_scene(path)
    path = _csv_scene(tmp_path, "time,torque\n0.0,1\n", 'columns = { torque = "torque" }\n'
                      "[inputs]\ntorque = 5.0")
    with pytest.raises(SceneError, match="torque is given twice"):
        load_scene(path)


def test_missing_scene_file(tmp_path):
    with pytest.raises(SceneError, match="does not exist"):
        load_scene(tmp_path / "none.toml")


# -- shipped scenes ------------------------------------------------------------------------------
def test_scenes_are_shipped():
    names = {p.stem for p in SHIPPED}
    assert {"paper_slip", "paper_stick_slip", "torque_reversal_backlash", "driveline_startup",
            "nvh_torsional", "driveline_torsional"} <= names


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_scene_runs(path):
    """Every shipped scene loads and runs over a short horizon with finite outputs; the mesh
    force carries the torque (mean within 25 % of T/rb1 over the second half)."""
    scene = load_scene(path).with_t_end(0.02)
    tr = run_or_skip(scene, "fast")
    n = int(round(0.02 / scene.outputs.interval))
    assert len(tr.time) == n + 1 and tr.time[-1] == 0.02
    for name in ("dte", "mesh_force", "friction_force", "output_torque", "gear1_speed"):
        assert np.all(np.isfinite(tr[name])), name
    w = tr.window(0.01)
    static = np.mean(tr["torque"][w]) / scene.params.rb1
    assert abs(np.mean(tr["mesh_force"][w]) - static) < 0.25 * abs(static)
    summ = tr.summary(scene.t_from)
    assert 0.0 <= summ["stick_ratio"] <= 1.0 and 0.0 <= summ["contact_loss_ratio"] <= 1.0
    if scene.effects.friction == "off":
        assert np.all(tr["friction_force"] == 0.0)


def test_paper_scenes_differ_only_in_friction_and_stick_only_with_stick_slip():
    slip = load_scene(ROOT / "examples/scenes/paper_slip.toml")
    stick = load_scene(ROOT / "examples/scenes/paper_stick_slip.toml")
    assert slip.params == stick.params == GearParams()
    assert (slip.effects.friction, stick.effects.friction) == ("nominal", "stick_slip")
    assert slip.inputs == stick.inputs
    # the first stick near the pitch point comes at about 0.015 s
    a, b = slip.with_t_end(0.02).run(), stick.with_t_end(0.02).run()
    assert not np.any(a["contact_state"] == 2)
    assert np.any(b["contact_state"] == 2) and b.ratios()["stick_ratio"] > 0.0


def test_torque_reversal_reaches_the_back_flank():
    """After the reversal (t >= 0.045 s) the back flanks carry the negative torque."""
    scene = load_scene(ROOT / "examples/scenes/torque_reversal_backlash.toml").with_t_end(0.07)
    tr = run_or_skip(scene, "fast")
    after = tr.time > 0.06
    assert np.all(np.isfinite(tr["dte"]))
    assert np.any(tr["contact_state"][after] == 3)
    assert np.mean(tr["mesh_force"][after]) < 0.0
    assert np.min(tr["dte"][after]) < -scene.effects.backlash  # across the clearance


def test_decimation_keeps_ratios_and_peaks():
    """A coarser output interval samples the signals but merges the step figures: the same
    ratios, peak force and event count as at the step."""
    fine = load_scene(ROOT / "examples/scenes/paper_stick_slip.toml").with_t_end(0.02)
    coarse = replace(fine, outputs=OutputSpec(interval=5e-4), solver=Solver(step=1e-4))
    a, b = fine.run(), coarse.run()
    assert coarse.every == 5 and len(b.time) == 41
    np.testing.assert_array_equal(b["dte"], a["dte"][::5])
    assert b.ratios(0.0) == pytest.approx(a.ratios(0.0), rel=1e-12, abs=1e-15)
    assert a.ratios(0.0)["stick_ratio"] > 0.0
    assert b["mesh_force_max"].max() == a["mesh_force_max"].max()
    assert b["n_events"].sum() == a["n_events"].sum() > 0


# -- the FMU as an engine --------------------------------------------------------------------------
FMU_SCENE = """
    t_end = 0.02
    [effects]
    friction = "stick_slip"
    [inputs.torque]
    kind = "ramp"
    from = 3900.0
    to = 2500.0
    t0 = 0.004
    t1 = 0.012
    [inputs.speed_rpm]
    kind = "step"
    before = 100.0
    after = 120.0
    at = 0.0105
    [solver]
    rtol = 1e-8
    step = 1e-4
    """


FMU_CASES = {"ramp_step_stick_slip": None, "torque_reversal_backlash": 0.06,
             "nvh_torsional": 0.01}  # scene (custom or shipped) -> horizon (s)


@pytest.mark.fmu
@pytest.mark.parametrize("case", list(FMU_CASES))
def test_fmu_engine_agrees_with_fast(tmp_path, fmu_path, case):
    """The FMU runs the same fast engine with the same held inputs (one input-table row per
    communication point), so it agrees to round-off: within 1e-9 of each signal's scale, and
    the contact states are equal."""
    pytest.importorskip("fmpy")
    if FMU_CASES[case] is None:
        scene = load_scene(write(tmp_path, FMU_SCENE))
    else:
        scene = load_scene(ROOT / f"examples/scenes/{case}.toml").with_t_end(FMU_CASES[case])
    a = run_or_skip(scene, "fast")
    try:
        b = scene.run("fmu", fmu_path=fmu_path)
    except SceneError as exc:
        pytest.skip(f"this FMU cannot run {case} yet: {exc}")
    assert b.meta["engine"] == "fmu"
    np.testing.assert_allclose(b.time, a.time, rtol=0, atol=1e-15)  # fmpy's grid: 1 ulp
    np.testing.assert_array_equal(b["torque"], a["torque"])
    np.testing.assert_array_equal(b["speed"], a["speed"])
    for name in ("dte", "mesh_force", "friction_force", "output_torque"):
        scale = max(np.max(np.abs(a[name])), 1e-300)
        assert np.max(np.abs(b[name] - a[name])) <= 1e-9 * scale, name
    np.testing.assert_array_equal(b["contact_state"], a["contact_state"])
    # the step figures after row 0 (which the FMU describes as an instant)
    np.testing.assert_allclose(b["stick_fraction"][1:], a["stick_fraction"][1:], atol=1e-9)
    if case == "ramp_step_stick_slip":  # the inputs changed and the run covers stick
        assert a["torque"][-1] == 2500.0 and a["speed"][-1] == pytest.approx(120 * RPM)
        assert np.any(a["contact_state"] == 2)
    elif case == "torque_reversal_backlash":  # the clearance reached the FMU
        assert np.any(b["contact_state"] == 3)


@pytest.mark.fmu
def test_fmu_refuses_what_it_cannot_express(tmp_path, fmu_path):
    pytest.importorskip("fmpy")
    (tmp_path / "k.csv").write_text("position_m,stiffness_n_per_m\n0,1e9\n0.03,2e9\n")
    scene = load_scene(write(tmp_path, '[effects.stiffness]\nkind = "table"\nfile = "k.csv"\n'))
    with pytest.raises(SceneError, match=r"FMU cannot express \[effects.stiffness\] kind"):
        scene.run("fmu", fmu_path=fmu_path)
    scene = load_scene(write(tmp_path, "[solver]\nstatic_start = false\n"))
    with pytest.raises(SceneError, match="static_start"):
        scene.run("fmu", fmu_path=fmu_path)


# -- command line and docs -----------------------------------------------------------------------
def test_cli_simulate_scene_json_csv_plot(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    scene = ROOT / "examples/scenes/paper_slip.toml"
    out, png = tmp_path / "run.csv", tmp_path / "run.png"
    rc = main(["simulate", str(scene), "--t-end", "0.01", "--json", "--out", str(out),
               "--plot", str(png)])
    assert rc == 0
    summ = json.loads(capsys.readouterr().out)
    assert summ["engine"] == "fast" and summ["scene"] == "paper_slip" and summ["t_end"] == 0.01
    assert summ["window_s"] == [0.005, 0.01]  # t_from 0.1 is past the new end: second half
    assert 0.8 * 3900 / RB1 < summ["mesh_force_n"]["mean"] < 1.2 * 3900 / RB1
    assert summ["dte_m_sampled"]["peak_to_peak"] >= 0 and summ["wall_time_s"] > 0
    assert summ["wall_time_per_simulated_s"] == pytest.approx(summ["wall_time_s"] / 0.01)
    names = load_scene(scene).outputs.names
    header = out.read_text().splitlines()[0]
    assert header == ",".join(("time", *names))  # plain names, units in docs/scenes.md
    assert len(out.read_text().splitlines()) == 1 + 101
    assert png.stat().st_size > 10_000


def test_cli_scene_errors_exit_2_naming_the_key(tmp_path, capsys):
    bad = write(tmp_path, "[gear]\nm1 = -3\n")
    assert main(["simulate", str(bad)]) == 2
    assert "[gear] m1 = -3.0 is out of range" in capsys.readouterr().err
    scene = str(ROOT / "examples/scenes/paper_slip.toml")
    assert main(["simulate", scene, "--mu", "0.1"]) == 2
    assert "--mu: set this in the scene file" in capsys.readouterr().err


def test_docs_list_every_key():
    doc = (ROOT / "docs" / "scenes.md").read_text()
    keys = [f.name for f in GearParams.__dataclass_fields__.values()]
    keys += ["pressure_angle_deg", "stiffness", "separation", "friction", "v_eps", "sliding",
             "stick_tie", "backlash", "dof", "mu_static", "stribeck_velocity",
             "scale_to_mean", "speed_rpm", "static_start", "rtol", "step", "interval",
             "t_from", "names", "t_end", "columns", "kind"]
    keys += list(OUTPUT_NAMES)
    missing = [k for k in keys if f"`{k}`" not in doc]
    assert not missing, missing


def test_schedules_sample_a_grid_as_they_do_point_by_point():
    """`sample` (one call for a whole grid, what the compiled recorder is fed) equals the
    pointwise schedule exactly, on both sides of every breakpoint."""
    t = np.r_[np.linspace(-0.1, 1.2, 1001), 0.5 - 1e-13, 0.5 + 1e-13]
    for f in (Constant(3.0), Ramp(1.0, 5.0, 0.2, 0.7), Step(1.0, 2.0, 0.5),
              Series((0.0, 0.5, 1.0), (1.0, 3.0, 2.0))):
        assert np.array_equal(f.sample(t), np.array([f(x) for x in t])), f
