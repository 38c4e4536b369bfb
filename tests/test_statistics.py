"""What the summaries, sweeps and the command line report: statistics over the whole
trajectory, the fast engine as the default, back-flank contact as contact, points outside the
model, standstill and user errors.

The mean mesh force has an expected value from the model itself. Gear 1's rotation
(coordinate u1 on the base circle, input shaft kr1 = 0 in Table 1) obeys
``m1 u1'' = Tr / rb1 - (F_mesh + c_m delta') + M_f / rb1``, with ``M_f`` the moment of the
tooth friction forces about gear 1's axis (arms s1m). Averaged over a window of length
``T_w`` in steady state the inertia term ``m1 du1'/T_w`` and the mesh damping ``c_m d(delta)/T_w``
vanish, so ``mean(F_mesh) = Tr/rb1 + mean(M_f)/rb1``: exactly ``Tr/rb1`` without friction,
and with friction off by the friction moment's mean, which changes sign at the pitch point
and is a few tenths of a per cent here (bounded below by ``mu`` times the arm ratio).
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from gearpair import RPM, Effects, GearParams, make_engine
from gearpair.cli import main
from gearpair.fast import FastEngine
from gearpair.results import simulate
from gearpair.scenes import SceneWarning, load_scene
from gearpair.sweep import SweepSettings, run_point, run_sweep

P = GearParams()
TR = 3900.0
QUICK = SweepSettings(transient_periods=60, transient_time=0.0, kept_periods=40, max_time=1.0,
                      min_periods=4)


def _mesh_period(rpm: float) -> float:
    return 2 * math.pi / (P.z1 * rpm * RPM)


# -- 1. statistics from the whole trajectory -------------------------------------------------
@pytest.mark.parametrize("rpm", [467.0, 1200.0])
def test_mean_mesh_force_is_tr_over_rb1_where_the_sampling_phase_locks(rpm):
    """Without friction the mean mesh force is Tr/rb1 (module docstring). The sweep samples 8
    times per mesh period at fixed phases and the summary here records at a phase-locked
    interval (8 per period too): their sample means are off by percents (checked below, so
    the test does bite), the reported means are not."""
    ideal = TR / P.rb1
    settings = QUICK.replace(friction="off")
    rec = run_point(0, "speed_rpm", rpm, settings)
    assert rec["status"] == "ok", rec["error"]
    assert rec["mesh_force_mean_kn"] * 1e3 == pytest.approx(ideal, rel=1e-3)
    tm = _mesh_period(rpm)
    traj = simulate(P, Effects(friction="off"), t_end=60 * tm, dt=tm / 8, torque=TR,
                    speed=rpm * RPM)
    summ = traj.summary(t_from=20 * tm)
    assert summ["mesh_force_n"]["mean"] == pytest.approx(ideal, rel=1e-3)
    w = traj.window(20 * tm)
    sampled = float(traj["mesh_force"][w].mean())
    assert abs(sampled / ideal - 1.0) > 5e-3  # the sample mean phase-locks
    # extremes over each step: the least and the peak bracket every sample and the mean
    f = summ["mesh_force_n"]
    assert f["min"] <= traj["mesh_force"][w].min() and f["max"] >= traj["mesh_force"][w].max()
    assert f["min"] < f["mean"] < f["max"]


def test_mean_mesh_force_with_friction_matches_a_finely_sampled_run():
    """With stick-slip friction the mean is Tr/rb1 less the friction moment's share (a few
    tenths of a per cent at 467 r/min); the sweep's and the summary's means agree with the
    mean of a run sampled every 2 us (about 1900 samples per mesh period) to 3e-4."""
    rpm = 467.0
    tm = _mesh_period(rpm)
    rec = run_point(0, "speed_rpm", rpm, QUICK)
    assert rec["status"] == "ok", rec["error"]
    coarse = simulate(P, Effects(), t_end=60 * tm, dt=tm / 8, torque=TR, speed=rpm * RPM,
                      rtol=QUICK.rtol)
    fine = simulate(P, Effects(), t_end=60 * tm, dt=2e-6, torque=TR, speed=rpm * RPM,
                    rtol=QUICK.rtol)
    t_from = 60 * tm - 40 * tm
    sampled_fine = float(fine["mesh_force"][fine.window(t_from)].mean())
    mean = coarse.summary(t_from)["mesh_force_n"]["mean"]
    assert mean == pytest.approx(sampled_fine, rel=3e-4)
    assert rec["mesh_force_mean_kn"] * 1e3 == pytest.approx(sampled_fine, rel=3e-4)
    share = mean / (TR / P.rb1) - 1.0
    assert -6e-3 < share < 0.0  # friction takes a small share, as measured at this point


def test_both_engines_integrate_the_mesh_force_alike():
    """The reference (Gauss points on scipy's dense output) and the fast engine (Runge-Kutta
    quadrature of its stages; slope-corrected trapezoid on the exact propagator) are two
    independent quadratures of the same trajectory: per-step means agree to 1e-7."""
    cases = [(Effects(), TR), (Effects(dof="torsional", stiffness="rectangular",
                                       friction="off", backlash=5e-5), -500.0)]
    for fx, torque in cases:
        means = []
        for name in ("reference", "fast"):
            e = make_engine(P, fx, name, rtol=1e-9)
            e.reset(0.0, abs(torque), 467 * RPM)
            means.append([e.advance(k * 1e-3, torque, 467 * RPM).mesh_force_mean
                          for k in range(1, 9)])
        np.testing.assert_allclose(means[0], means[1], rtol=1e-7)


def test_step_mean_is_the_integral_of_a_fine_record():
    """One coarse step's mean equals the trapezoid mean of the same run recorded every 1 us
    (no stiffness jumps inside: constant stiffness, through Runge-Kutta with stick-slip and
    through the exact propagator), and with the time-varying stiffness it does not depend on
    how the interval is cut into steps."""
    cases = (Effects(stiffness="constant"), Effects(), Effects(dof="torsional",
                                                                stiffness="constant",
                                                                friction="off"))
    for fx in cases:
        means = []
        for grid in (np.array([0.01, 0.012]), np.linspace(0.01, 0.012, 2001)):
            e = FastEngine(P, fx, rtol=1e-10)
            e.reset(0.0, TR, 467 * RPM)
            e.advance(0.01, 3000.0, 467 * RPM)  # a torque step: the mesh rings
            rec = e.run(grid, TR, 467 * RPM)
            means.append(float(np.mean(rec["mesh_force_mean"][1:])))
        f = rec["mesh_force"]
        assert means[0] == pytest.approx(means[1], rel=1e-8)
        if fx.stiffness.kind == "constant":
            assert means[0] == pytest.approx(np.mean(0.5 * (f[1:] + f[:-1])), rel=1e-6)


EXTREME_CASES = [(Effects(), TR), (Effects(friction="off", stiffness="rectangular"), TR),
                 (Effects(dof="torsional", stiffness="rectangular", friction="off",
                          backlash=5e-5), -500.0)]


def _extremes(traj, t_from):
    """Least and greatest mesh force over the intervals after ``t_from`` (the summary's)."""
    w = traj.time > t_from + 1e-12
    return float(traj["mesh_force_min"][w].min()), float(traj["mesh_force_max"][w].max())


@pytest.mark.parametrize("fx, torque", EXTREME_CASES[:2])
def test_mesh_force_extremes_do_not_depend_on_the_output_step(fx, torque):
    """min/max are the trajectory's extremes over every step (turning points located inside
    Runge-Kutta steps and exact stretches), not samples at step ends: at 467 r/min they agree
    across output steps 1e-3, 1e-4, 1e-5 s to the integration tolerance, where samples
    differed by up to 1.3 % (min 4468 / 4411 / 4409 N)."""
    got = [_extremes(simulate(P, fx, t_end=0.2, dt=dt, torque=torque, speed=467 * RPM,
                              rtol=1e-9), 0.1) for dt in (1e-3, 1e-4, 1e-5)]
    for lo, hi in got[1:]:
        assert lo == pytest.approx(got[0][0], rel=1e-7)
        assert hi == pytest.approx(got[0][1], rel=1e-7)


@pytest.mark.parametrize("fx, torque", EXTREME_CASES[:2])
def test_mesh_force_extremes_match_a_densely_sampled_run(fx, torque):
    """The extremes bound the mesh force of the same run recorded every 1 us (its output
    samples, not its summary: a sharp dip falls 2 N below them), and equal the force
    sampled every 1 ns over the output interval that holds each (an engine run of its own,
    ended on those instants), to 1e-6 of the peak (a peak on a pair's entry, where the
    force jumps, is missed by up to 1 ns of its fall)."""
    w = 467 * RPM
    coarse = simulate(P, fx, t_end=0.2, dt=1e-4, torque=torque, speed=w, rtol=1e-9)
    lo, hi = _extremes(coarse, 0.1)
    fine = simulate(P, fx, t_end=0.2, dt=1e-6, torque=torque, speed=w, rtol=1e-9)
    f = fine["mesh_force"][fine.time >= 0.1 - 1e-12]
    tol = 1e-8 * hi
    assert lo - tol <= f.min() <= lo + 5e-4 * hi
    assert hi - 5e-4 * hi <= f.max() <= hi + tol
    rows = np.flatnonzero(coarse.time > 0.1 + 1e-12)
    for got, name, pick in ((lo, "mesh_force_min", np.min), (hi, "mesh_force_max", np.max)):
        i = rows[np.argmin(coarse[name][rows]) if pick is np.min else
                 np.argmax(coarse[name][rows])]
        ta, tb = coarse.time[i - 1], coarse.time[i]
        e = make_engine(P, fx, "fast", rtol=1e-9)
        e.reset(0.0, torque, w)
        e.advance(ta, torque, w)
        ns = e.run(np.linspace(ta, tb, 100001), torque, w)["mesh_force"]
        assert float(pick(ns)) == pytest.approx(got, abs=1e-6 * hi)


@pytest.mark.parametrize("fx, torque", [EXTREME_CASES[0], EXTREME_CASES[2]])
def test_both_engines_locate_the_same_mesh_force_extremes(fx, torque):
    """The reference (bounded Brent on scipy's dense output where a step's samples could
    hide a new extreme) and the fast engine (Hermite turning points refined on its continuous
    extension; quintic Hermite on exact stretches) find the same least and greatest force
    in every step, on the drive and the back flank."""
    got = []
    for name in ("reference", "fast"):
        e = make_engine(P, fx, name, rtol=1e-9)
        e.reset(0.0, abs(torque), 467 * RPM)
        steps = [e.advance(k * 1e-3, torque, 467 * RPM) for k in range(1, 9)]
        got.append([(s.mesh_force_min, s.mesh_force_max) for s in steps])
    scale = float(np.abs(got[0]).max())
    np.testing.assert_allclose(got[0], got[1], rtol=0, atol=1e-7 * scale)


# -- 2. the fast engine is the default --------------------------------------------------------
def test_fast_engine_is_the_default_and_start_up_is_reported_apart(capsys):
    assert isinstance(make_engine(P, Effects()), FastEngine)
    traj = simulate(P, Effects(), t_end=0.005)
    assert traj.meta["engine"] == "fast"
    assert traj.meta["startup_s"] > 0 and traj.meta["wall_time_s"] > 0
    assert main(["simulate", "--t-end", "0.005", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["engine"] == "fast" and out["startup_s"] > 0
    assert out["wall_time_per_simulated_s"] == pytest.approx(out["wall_time_s"] / 0.005)


# -- 3. back-flank contact is contact; points outside the model --------------------------------
def test_back_flank_is_reported_as_contact_not_loss(capsys):
    assert main(["simulate", "examples/scenes/torque_reversal_backlash.toml", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["contact_loss_ratio"] == 0.0
    # every step on the back flank; each step's fraction is a difference of accumulated
    # times over the step, so the mean is 1 to rounding, not always exactly
    assert out["back_contact_ratio"] == pytest.approx(1.0, abs=1e-12)
    assert out["mesh_force_n"]["mean"] < -30e3  # the back flanks carry the load


def test_fmu_summary_matches_the_engine_and_reports_start_up_apart(fmu_path):
    """``--engine fmu``: the FMU's per-step outputs (back_fraction, mesh_force_mean, _min,
    _max) give the summary the engine's figures, the back-contact ratio included, and the
    FMU's start-up (extraction, instantiation, initialization: building the engine) is
    reported apart from the run's wall time."""
    pytest.importorskip("fmpy")
    scene = load_scene("examples/scenes/torque_reversal_backlash.toml").with_t_end(0.08)
    fmu = scene.run("fmu", fmu_path=fmu_path)
    fast = scene.run("fast")
    assert fmu.meta["startup_s"] > 0 and fmu.meta["wall_time_s"] > 0
    got, ref = fmu.summary(0.07), fast.summary(0.07)
    assert got["back_contact_ratio"] == ref["back_contact_ratio"] == 1.0
    assert set(got["mesh_force_n"]) == {"min", "mean", "max"}
    for key in ("min", "mean", "max"):
        assert got["mesh_force_n"][key] == pytest.approx(ref["mesh_force_n"][key], rel=1e-9)


def test_a_record_without_step_figures_names_its_sampled_statistics():
    """A record lacking a step figure (an FMU built before those outputs existed) gives the
    statistics of its output samples under names that say so, never as plain min/mean."""
    traj = simulate(P, Effects(backlash=1e-4), t_end=0.01, torque=-TR, dt=1e-4)
    for k in ("back_fraction", "mesh_force_mean", "mesh_force_min", "mesh_force_max"):
        del traj.data[k]
    got = traj.summary(0.005)
    f = traj["mesh_force"][traj.window(0.005)]
    assert "back_contact_ratio" not in got and got["back_contact_ratio_sampled"] == 1.0
    assert got["mesh_force_n"] == {"min_sampled": f.min(), "mean_sampled": f.mean(),
                                   "max_sampled": f.max()}


def test_negative_torque_without_backlash_is_invalid_not_ok():
    res = run_sweep("torque", [-3900.0, 3900.0], QUICK.replace(kept_periods=8,
                    transient_periods=8), scheduler="serial", retries=1, progress=False)
    bad, good = res.records
    assert bad["status"] == "invalid" and "backlash" in bad["error"]
    assert bad["attempts"] == 1 and res.retried == 0
    assert bad["poincare"] == [] and math.isnan(bad["dte_mean_um_sampled"])
    assert good["status"] == "ok"


def test_simulate_says_when_a_run_lies_outside_the_model(capsys):
    assert main(["simulate", "--torque", "-100", "--t-end", "0.005", "--json"]) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert "outside the model" in out["outside_model"] and "backlash" in out["outside_model"]
    assert cap.err.startswith("gearpair: warning: torque = -100 N.m < 0 without backlash")
    assert main(["simulate", "--t-end", "0.005", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["outside_model"] is None


# -- 4. standstill and user errors ------------------------------------------------------------
def test_standstill_runs_fast_and_is_refused_clearly_by_the_reference(capsys):
    assert main(["simulate", "--speed-rpm", "0", "--t-end", "0.01", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["stick_ratio"] == 1.0
    assert out["mesh_force_n"]["mean"] == pytest.approx(TR / P.rb1, rel=2e-3)
    rc = main(["simulate", "--speed-rpm", "0", "--t-end", "0.01", "--engine", "reference"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "standstill" in err and "fast" in err
    # the reference runs standstill where its stick constraints are distinct
    e = make_engine(P, Effects(sliding="full"), "reference", rtol=1e-8)
    e.reset(0.0, TR, 0.0)
    assert e.advance(1e-3, TR, 0.0).stick_fraction == 1.0


def test_cli_output_paths_are_created_or_refused_before_the_run(tmp_path, capsys):
    out, fig = tmp_path / "new" / "run.csv", tmp_path / "other" / "run.png"
    assert main(["simulate", "--t-end", "0.002", "--out", str(out), "--plot", str(fig)]) == 0
    assert out.is_file() and fig.is_file()
    capsys.readouterr()
    for argv in (["--plot", str(tmp_path / "run.xyz")], ["--out", str(tmp_path)]):
        rc = main(["simulate", "--t-end", "0.002", *argv])
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and err.startswith("gearpair: error: ")


def test_an_input_csv_column_no_input_uses_is_reported(tmp_path, capsys):
    (tmp_path / "in.csv").write_text("time,torque,sped_rpm\n0,3900,100\n0.01,3900,100\n")
    scene = tmp_path / "scene.toml"
    scene.write_text('t_end = 0.002\n[inputs.csv]\nfile = "in.csv"\n')
    with pytest.warns(SceneWarning, match=r"'sped_rpm'.*closest input name: 'speed_rpm'"):
        load_scene(scene)
    assert main(["simulate", str(scene), "--json"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("gearpair: warning: ") and "sped_rpm" in err
    # mapped explicitly: the file's other columns are the user's business
    scene.write_text('t_end = 0.002\n[inputs.csv]\nfile = "in.csv"\n'
                     'columns = { time = "time", torque = "torque" }\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_scene(scene)
