"""Sweeps on dask: Poincare analysis on synthetic signals, one sweep point against
the engine's own counters and `results.simulate`, and parallel sweeps that report failed
points instead of dropping them."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from gearpair import RPM, Effects, GearParams, make_engine
from gearpair import analysis as an
from gearpair.results import simulate
from gearpair.sweep import (
    COLUMNS,
    SweepSettings,
    parse_values,
    read_result,
    record_periods,
    run_point,
    run_sweep,
)

# Short points: 10 discarded, 10 kept mesh periods (about 0.36 s simulated at 100 r/min).
QUICK = SweepSettings(transient_periods=10, transient_time=0.0, kept_periods=10, max_time=0.5,
                      min_periods=4)


# -- analysis on synthetic signals -------------------------------------------------------------
def _signal(periods: int, n: int, half: float = 0.0):
    """Mesh-periodic test signal sampled n times per period (period 1), plus a component at
    half the mesh frequency of amplitude ``half`` (period 2)."""
    t = np.arange(periods * n) / n  # time in mesh periods
    x = 3.0 + 2.0 * np.sin(2 * np.pi * t + 0.3) + 0.4 * np.cos(4 * np.pi * t)
    return t, x + half * np.sin(np.pi * t + 0.7)


def test_period_one_signal_gives_one_poincare_value():
    _, x = _signal(40, 16)
    sec = an.poincare_every(x, 16, skip_periods=5)
    assert sec.size == 35
    assert an.periodicity(sec, 1e-9) == 1
    vals = an.distinct_values(sec, 1e-9)
    assert vals.size == 1
    assert vals[0] == pytest.approx(3.0 + 2.0 * np.sin(0.3) + 0.4, abs=1e-12)


def test_period_two_signal_gives_two_poincare_values():
    _, x = _signal(40, 16, half=0.5)
    sec = an.poincare_every(x, 16, skip_periods=4, offset=3)
    assert an.periodicity(sec, 1e-9) == 2
    vals = an.distinct_values(sec, 1e-9)
    assert vals.size == 2
    # the two values differ by twice the half-order component at that phase
    ph = np.pi * 3 / 16 + 0.7
    assert vals[1] - vals[0] == pytest.approx(2 * 0.5 * abs(np.sin(ph)), rel=1e-9)
    d1, d2 = an.adjacent_period_difference(x, 16)
    assert d1 > 0.1 and d2 < 1e-12


def test_aperiodic_sequence_has_no_period():
    x = np.empty(200)
    x[0] = 0.3
    for i in range(199):  # logistic map in its chaotic regime
        x[i + 1] = 3.9 * x[i] * (1 - x[i])
    assert an.periodicity(x, 1e-6) == 0
    assert an.distinct_values(x, 1e-6).size > 150


def test_poincare_interp_samples_at_the_period():
    t = np.linspace(0.0, 10.0, 100_001)
    x = np.sin(2 * np.pi * t / 0.5)
    s = an.poincare_interp(t, x, 0.5, t_from=2.0, phase=0.25)
    assert s.size == 16  # 2.125, 2.625, ..., 9.625
    assert np.allclose(s, 1.0, atol=1e-6)


def test_order_amplitudes_are_exact_on_whole_periods():
    _, x = _signal(20, 16, half=0.5)
    a = an.order_amplitudes(x, 16, (0.5, 1.0, 1.5, 2.0, 3.0))
    assert a[0.5] == pytest.approx(0.5, abs=1e-12)
    assert a[1.0] == pytest.approx(2.0, abs=1e-12)
    assert a[2.0] == pytest.approx(0.4, abs=1e-12)
    assert a[1.5] < 1e-12 and a[3.0] < 1e-12
    with pytest.raises(ValueError, match="Nyquist"):
        an.order_amplitudes(x, 16, (8.0,))
    f, amp = an.amplitude_spectrum(x, 1.0 / 16)
    assert f[np.argmax(amp)] == pytest.approx(1.0)


def test_mesh_period_and_section_offset():
    w = 100 * RPM
    assert an.mesh_period(33, w) == pytest.approx(1.0 / 55.0, rel=1e-14)  # 33 * 100 / 60 Hz
    with pytest.raises(ValueError, match="positive speed"):
        an.mesh_period(33, 0.0)
    off = an.section_offset([0.0, 0.75, 0.9129], 8)
    ph = (np.arange(8) + off) / 8
    d = np.abs(ph[:, None] - np.array([0.0, 0.75, 0.9129, 1.0])[None, :])
    assert 0 < off < 1 and d.min() > 0.02


def test_periods_cap_long_mesh_periods():
    s = SweepSettings()
    assert s.periods(1 / 55) == (100, 100)            # 100 r/min: 1.8 s + 1.8 s
    n_t, n_k = s.periods(1 / 330)                      # 600 r/min: at least 1 s discarded
    assert n_t == 330 and n_k == 100
    n_t, n_k = s.periods(60 / 66)                      # 2 r/min: floor of 16 periods each
    assert (n_t, n_k) == (16, 16)
    n_t, n_k = s.periods(60 / 660)                     # 20 r/min: about 3 s + 3 s
    assert n_k % 2 == 0 and abs((n_t + n_k) * 60 / 660 - 6.0) < 0.2


def test_parse_values():
    assert parse_values("0.01,0.02, 0.05") == [0.01, 0.02, 0.05]
    assert parse_values("2:600:300")[:2] == [2.0, 4.0] and len(parse_values("2:600:300")) == 300
    with pytest.raises(ValueError):
        parse_values("1:2")
    # the CLI prints this message as its one line: it must name the argument, not int()'s text
    with pytest.raises(ValueError, match=r"values '1:2:x': use start:stop:num"):
        parse_values("1:2:x")


# -- one point ---------------------------------------------------------------------------------
def test_point_ratios_match_the_engine_counters_and_simulate():
    """The point's ratios are the engine's own stick/separation time over the kept window,
    and agree with `results.simulate` + `Trajectory.ratios` on another output grid."""
    rec = run_point(0, "speed_rpm", 100.0, QUICK)
    assert rec["status"] == "ok", rec["error"]
    tm = 1 / 55
    assert rec["mesh_period_s"] == pytest.approx(tm)
    assert (rec["transient_periods"], rec["kept_periods"]) == (10, 10)
    assert len(rec["poincare"]) == 10
    # the same run stepped by hand: read the engine's cumulative stick time at the window ends
    p, fx = GearParams(), Effects()
    r = record_periods(p, fx, 3900.0, 100 * RPM, 10, 10, 8, QUICK.rtol)
    h = tm / 8
    t_from, t_end = r["time"][0] - h, r["time"][-1]
    assert t_end - t_from == pytest.approx(10 * tm, rel=1e-12)
    eng = make_engine(p, fx, "fast", rtol=QUICK.rtol)
    eng.reset(0.0, 3900.0, 100 * RPM)
    eng.advance(t_from, 3900.0, 100 * RPM)
    k0 = eng.stick_time
    eng.advance(t_end, 3900.0, 100 * RPM)
    direct = (eng.stick_time - k0) / (t_end - t_from)
    assert 0.03 < rec["stick_ratio"] < 0.2  # the default point sticks (README)
    assert rec["stick_ratio"] == pytest.approx(direct, abs=2e-4)
    assert rec["contact_loss_ratio"] == 0.0
    # an independent output grid (dt incommensurate with the mesh period)
    dt = tm / (7 + math.sqrt(2) / 10)
    traj = simulate(p, fx, t_end=t_end, torque=3900.0, speed=100 * RPM, dt=dt, engine="fast",
                    rtol=QUICK.rtol)
    ratios = traj.ratios(t_from=t_end - 10 * tm)
    assert rec["stick_ratio"] == pytest.approx(ratios["stick_ratio"], abs=2e-3)
    # the Poincare samples are the DTE at the section instants, near phase 0.7 of the period
    assert abs(rec["section_phase"] - 0.7) <= 1 / 16
    j0 = int(np.argmin(np.abs((np.arange(8) + r["offset"]) / 8 - rec["section_phase"])))
    assert np.array(rec["poincare"]) == pytest.approx(r["dte"][j0::8], rel=1e-12)
    assert rec["dte_min_um_sampled"] > 0 and rec["mesh_force_min_kn"] > 15


def test_point_never_raises():
    """Values the validation refuses are invalid points, not failed runs."""
    rec = run_point(3, "mu", -0.5, QUICK)
    assert rec["status"] == "invalid" and "mu" in rec["error"] and "allowed" in rec["error"]
    assert rec["index"] == 3 and math.isnan(rec["stick_ratio"]) and rec["poincare"] == []
    rec = run_point(0, "speed_rpm", 0.0, QUICK)
    assert rec["status"] == "invalid" and "speed" in rec["error"]
    rec = run_point(0, "no_such_thing", 1.0, QUICK)
    assert rec["status"] == "invalid" and "cannot sweep" in rec["error"]


# -- sweeps on dask ----------------------------------------------------------------------------
def test_local_cluster_sweep_matches_serial_and_reports_failures(tmp_path):
    values = [0.0, 0.02, -1.0, 0.05]  # -1 is out of range: reported, kept, not retried
    res = run_sweep("mu", values, QUICK, workers=2, retries=1, progress=False)
    assert res.scheduler == "local" and res.workers == 2
    assert [r["index"] for r in res.records] == [0, 1, 2, 3]
    assert [r["status"] for r in res.records] == ["ok", "ok", "invalid", "ok"]
    bad = res.records[2]
    # a refused value is not retried with a tighter tolerance (it cannot help)
    assert bad["attempts"] == 1 and bad["rtol"] == QUICK.rtol
    assert "mu = -1.0" in bad["error"]
    assert res.retried == 0 and len(res.failed) == 0 and len(res.invalid) == 1
    assert res.throughput > 0 and "1 invalid" in res.report()
    assert "INVALID point 2" in res.report()
    # the parallel records equal a serial computation of the same points
    for i in (0, 1, 3):
        serial = run_point(i, "mu", values[i], QUICK)
        for key in ("stick_ratio", "contact_loss_ratio", "dte_mean_um_sampled",
                    "mesh_force_mean_kn", "mesh_force_max_kn"):
            assert res.records[i][key] == serial[key], key
        assert res.records[i]["poincare"] == serial["poincare"]
    rk = [r["stick_ratio"] for r in res.records]
    assert rk[0] == 0.0 and 0.0 < rk[1] < rk[3]  # no friction, no stick; more with mu
    files = res.write(tmp_path / "mu")
    with open(files["csv"], newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == COLUMNS and len(rows) == 5
    row = dict(zip(rows[0], rows[3], strict=True))
    assert row["status"] == "invalid" and "mu = -1.0" in row["error"] and row["value"] == "-1"
    with open(files["poincare"], newline="") as fh:
        assert sum(1 for _ in fh) == 1 + 3 * 10
    assert (tmp_path / "mu.png").stat().st_size > 5000
    back = read_result(tmp_path / "mu")
    assert back.settings == QUICK and back.values == values
    assert back.records[1]["stick_ratio"] == pytest.approx(rk[1], rel=1e-9)
    assert back.records[1]["poincare"] == pytest.approx(res.records[1]["poincare"], rel=1e-8)


def test_cli_sweep_on_a_running_scheduler(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    from gearpair.cli import main

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None,
                                  scheduler_kwargs={"dashboard_address": ":0"}) as cluster:
        # a negative torque without backlash lies outside the model: an invalid point
        # (values starting with "-" go after "--", the options first)
        rc = main(["sweep", "--scheduler", cluster.scheduler_address, "--speed-rpm", "150",
                   "--out", str(tmp_path / "sp"), "--transient-periods", "10",
                   "--transient-time", "0", "--kept-periods", "10", "--retries", "0",
                   "torque", "--", "-1000,3900"])
    cap = capsys.readouterr()
    assert rc == 1  # a point is invalid: reported in the CSV and on stderr, not dropped
    assert "points/s" in cap.err and "INVALID point 0" in cap.err
    assert '"throughput_points_per_s"' in cap.out
    with open(tmp_path / "sp.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["invalid", "ok"]
    assert "torque" in rows[0]["error"] and rows[0]["attempts"] == "1"
    assert float(rows[1]["stick_ratio"]) > 0.05  # 150 r/min sticks (Fig. 15 range)
    assert (tmp_path / "sp.png").stat().st_size > 5000
