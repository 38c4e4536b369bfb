"""Contact events that must not be missed (issue 38): re-contact microseconds after a
separation, back-flank impact and drive-flank tension after a torque reversal, zero
damping; the guard after every step, which locates a missed event and redoes the step;
unbounded responses reported; a seeded random search.

Every completed run is checked at every output sample: the contact state agrees with the
geometry (`assert_state_matches_geometry`) and the DTE stays within its bound
(`Model.dte_bound`).
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from gearpair import RPM, Effects, GearParams, Model
from gearpair.engine import (
    CONTACT_BACK,
    CONTACT_SEPARATED,
    G_START,
    RunFailure,
    run_failure_message,
)
from gearpair.inputs import Function, Step
from gearpair.results import simulate

ROOT = Path(__file__).resolve().parents[1]
# a located event leaves the state at most t_tol (1e-12 s or so) past the switch; the DTE
# moves by at most ~1 m/s there, and samples next to an event are rare: 1e-10 m is loose
# enough for rounding and far below any missed contact (micrometres and growing)
TOL = 1e-10


def assert_state_matches_geometry(tr, params: GearParams, effects: Effects) -> None:
    """At every sample: apart means no overlap of either flank, a flank in contact carries
    no tension, and no flank is compressed past `Model.dte_bound`."""
    d, cs = tr["dte"], tr["contact_state"]
    b = math.inf if effects.backlash is None else effects.backlash
    drive = (cs != CONTACT_SEPARATED) & (cs != CONTACT_BACK)
    where = np.flatnonzero(drive & (d < -TOL))
    assert where.size == 0, f"drive flank in tension at t = {tr.time[where[:3]]}"
    where = np.flatnonzero((cs == CONTACT_SEPARATED) & ((d > TOL) | (d < -b - TOL)))
    assert where.size == 0, f"apart with the flanks overlapping at t = {tr.time[where[:3]]}"
    where = np.flatnonzero((cs == CONTACT_BACK) & (d > -b + TOL))
    assert where.size == 0, f"back flank in tension at t = {tr.time[where[:3]]}"
    c0, c1 = Model.build(params, effects).dte_bound()
    lim = c0 + c1 * np.abs(tr["torque"])
    assert np.all(d <= lim) and np.all(d >= -b - lim)


def run(params, effects, **kw):
    tr = simulate(params, effects, **kw)
    assert_state_matches_geometry(tr, params, effects)
    return tr


# -- the cases of the issue -----------------------------------------------------------------
def test_recontact_microseconds_after_a_separation_is_seen():
    """Class A: rectangular stiffness at 5000 r/min separated at t = 0.2821 s and regained
    contact 13.5 us later, inside one sample spacing (13.8 us); the separation left the DTE
    at exactly 0.0, so the flank function started the free flight at 0 and its fall never
    counted: the gears flew apart (0.42 m at 0.735 s)."""
    p, fx = GearParams(), Effects(friction="off", stiffness="rectangular")
    tr = run(p, fx, t_end=0.35, torque=1000.0, speed=5000 * RPM, dt=1e-4)
    assert np.abs(tr["dte"]).max() < 20e-6
    loss = tr.ratios(t_from=0.05)["contact_loss_ratio"]
    assert 0.05 < loss < 0.8  # it does lose contact (the case is about re-contact)


def test_potential_energy_impacts_with_backlash_stay_in_mesh():
    """Class A with the potential-energy law: backlash 1e-4 m, 10 kN.m, 5000 r/min ran
    away at 0.0916 s; the reference engine gives a contact-loss ratio of 0.33."""
    p, fx = GearParams(), Effects(friction="off", backlash=1e-4)
    tr = run(p, fx, t_end=0.1, torque=10000.0, speed=5000 * RPM, dt=1e-4)
    assert np.abs(tr["dte"]).max() < 0.5e-3
    assert tr.ratios()["contact_loss_ratio"] == pytest.approx(0.33, abs=0.02)


def test_exact_propagator_finds_the_recontact_after_a_start_at_zero():
    """Found by scripts/contact_scan.py (seed 2, run 897): friction off, rectangular law, so
    the exact propagator runs. A separation at t = 0.8018747 s leaves the DTE at exactly 0;
    the free flight's flank function starts there, counted as positive, and the regula
    falsi put its next point on that start (a root itself, where rounding reads -0.0): the
    state switched back and forth at one instant until the event cap (before the start
    rule: the re-contact 6 us later was never seen and the DTE reached 54 m)."""
    p, fx = GearParams(), Effects(friction="off", stiffness="rectangular")
    tr = run(p, fx, t_end=0.81, torque=186.72924640958536, speed=33.48409152366052,
             dt=1e-4)
    assert np.abs(tr["dte"]).max() < 5e-6


def test_zero_damping_stick_slip_keeps_contact():
    """Class A with no damping at all (damping_ratio 0): failed at t = 0.0814 s."""
    p = GearParams(damping_ratio=0.0)
    tr = run(p, Effects(), t_end=0.1, torque=3900.0, speed=3000 * RPM, dt=1e-4)
    assert np.abs(tr["dte"]).max() < 100e-6


def test_torque_reversal_reaches_the_back_flank():
    """Class B: a 10 kN.m reversal through 1 mm of backlash ended apart past the back flank
    (-7.5 km at 2 s). The gears must end on the back flanks, deflected by the static
    deflection past the clearance."""
    b = 1e-3
    p, fx = GearParams(), Effects(friction="off", backlash=b)
    tr = run(p, fx, t_end=0.54, torque=Step(10000.0, -10000.0, 0.5), speed=1000 * RPM,
             dt=1e-4)
    late = tr.time > 0.53
    assert np.all(tr["contact_state"][late] == CONTACT_BACK)
    assert np.all(tr["dte"][late] < -b)
    assert np.all(tr["dte"][late] > -b - 0.2e-3)


def test_reversal_does_not_leave_the_drive_flank_in_tension():
    """Class C: with regularized friction and 10 um of backlash the drive flank stayed in
    contact under -162 kN after a reversal; the back-contact ratio must go to ~1."""
    p, fx = GearParams(), Effects(friction="regularized", backlash=1e-5)
    tr = run(p, fx, t_end=0.52, torque=Step(10000.0, -10000.0, 0.5), speed=100 * RPM,
             dt=1e-4)
    assert tr.ratios(t_from=0.51)["back_contact_ratio"] > 0.95
    assert tr["mesh_force"][-1] < 0.0


def test_slow_reversal_through_zero_with_backlash():
    """A slow torque oscillation through zero (backlash 1e-4 m): in class B the state stayed
    apart up to 1.27 um past the back flank with zero force."""
    p, fx = GearParams(), Effects(friction="off", backlash=1e-4)
    tr = run(p, fx, t_end=0.5, torque=Function(lambda t: 50.0 * math.cos(4.0 * math.pi * t)),
             speed=1000 * RPM, dt=1e-4)
    assert np.any(tr["contact_state"] == CONTACT_BACK)


def test_unbounded_response_is_reported():
    """Class D: backlash 1e-5 m, 10 kN.m, 7250 r/min grows without bound (1.8 mm at 0.04 s,
    1e10 m by 2 s; the reference engine stops at the same instant, 0.0263322884 s, in 23 s
    of run time: docs/limits.md). The run stops with a RunFailure (a ValueError) that names
    the time, the contact state, the DTE and the bound."""
    with pytest.raises(RunFailure, match=r"unbounded response: at t = 0\.0263\d+ s .*DTE"):
        simulate(GearParams(), Effects(backlash=1e-5), t_end=0.04, torque=10000.0,
                 speed=7250 * RPM, dt=1e-4)


@pytest.mark.parametrize("engine", ["fast", "reference"])
def test_guard_stops_a_state_past_the_bound_in_both_engines(engine):
    """The guard after every step, in both engines: a state compressed 80 times its static
    deflection (past the bound, 0.1 module plus 20 static deflections at km_mean) stops the
    first step with a RunFailure."""
    from gearpair import make_engine

    e = make_engine(GearParams(), Effects(backlash=1e-5), engine)
    e.reset(0.0, 10000.0, 100 * RPM, static=True)
    st = e.get_state()
    st["y"] = np.array(st["y"], dtype=float)
    st["y"][:6] *= 80.0
    e.set_state(st)
    with pytest.raises(RunFailure, match="unbounded response: at t = .* on the drive flanks"):
        e.advance(1e-4, 10000.0, 100 * RPM)


# -- locate and redo: a missed event is found and the step redone, not the run stopped -------
# A pair at rest with the flanks just touching (zero torque: the DTE and every rate exactly
# 0), then a negative torque: the drive flank goes into tension at once. The start rule leaves
# a flank function at zero and at rest as it is (`events.start_flanks`: marking it would let
# rounding noise chatter), so the scan sees no fall (a fall starts above zero) and the guard
# finds the flank in tension at the step's end. Before locate-and-redo both engines stopped
# there: "missed contact event: at t = 3.3e-05 s the teeth are on the drive flanks with DTE =
# -3.4e-07 m". Now the engine locates the event in that step and redoes the rest apart.
REDO_PATHS = {  # the fast engine's ways through a step: effects, FastOptions
    "dop853": (Effects(friction="off"), {}),
    "dop853 one sample per step": (Effects(friction="off"), {"sample_spacing": 1e-3}),
    "dop853 fine samples": (Effects(friction="off"), {"sample_spacing": 1e-7}),
    "dp5": (Effects(friction="off"), {"method": "dp5"}),
    "stick-slip": (Effects(), {}),
    "exact propagator": (Effects(friction="off", stiffness="rectangular"), {}),
    "rectangular by Runge-Kutta": (Effects(friction="off", stiffness="rectangular"),
                                   {"exact_lti": False}),
}


def _touching_at_rest(engine: str, effects: Effects, **options):
    from gearpair import make_engine

    e = make_engine(GearParams(), effects, engine, **options)
    e.reset(0.0, 0.0, 100 * RPM, static=True)
    y = np.asarray(e.get_state()["y"], dtype=float)
    # the premise: a flank function at zero and at rest, which the start rule leaves alone
    assert e.outputs().dte == 0.0 and not np.any(y[6:12])
    return e


@pytest.mark.parametrize("path", REDO_PATHS)
def test_fast_engine_locates_a_missed_event_and_redoes_the_step(path):
    """The event is located inside the step by the event search: with t_tol = 1e-9 s its
    instant lies in (0, 1e-9] s (a switch at the step's start, as the start rule makes,
    would be at exactly 0, and a stop raises). The forces the scan saw past it, in tension,
    are dropped: the least mesh force stays 0."""
    fx, opts = REDO_PATHS[path]
    e = _touching_at_rest("fast", fx, t_tol=1e-9, **opts)
    s = e.advance(1e-3, -1000.0, 100 * RPM)
    t_parted = (1.0 - s.separation_fraction) * 1e-3
    assert 0.0 < t_parted <= 1e-9 * (1.0 + 1e-6)
    assert s.n_events == 1
    assert s.mesh_force_min == 0.0 and s.mesh_force_max == 0.0
    o = e.outputs()
    assert o.contact_state == CONTACT_SEPARATED and o.dte < -1e-4


def test_reference_engine_locates_a_missed_event_and_redoes_the_step(monkeypatch):
    """The same in the reference engine (`ReferenceEngine._missed` finds the function, the
    event search places it at the step's start: no point after it is above zero)."""
    from gearpair.reference import ReferenceEngine

    found = []
    missed = ReferenceEngine._missed

    def spy(self, *args):
        m = missed(self, *args)
        found.append(m.size)
        return m

    monkeypatch.setattr(ReferenceEngine, "_missed", spy)
    e = _touching_at_rest("reference", Effects(friction="off"))
    s = e.advance(1e-3, -1000.0, 100 * RPM)
    assert found[0] == 1 and sum(found) == 1
    assert s.separation_fraction == 1.0 and s.n_events == 1 and s.mesh_force_min == 0.0
    assert e.outputs().contact_state == CONTACT_SEPARATED


def test_redone_reversal_from_rest_reaches_the_back_flank_in_both_engines():
    """A run that holds zero torque, then reverses it (backlash 1e-5 m): the missed event is
    redone, the gears cross the backlash and settle on the back flanks; both engines give
    the same ratios (to 1e-9 when written)."""
    p, fx = GearParams(), Effects(friction="off", backlash=1e-5)
    kw = dict(t_end=0.01, torque=Step(0.0, -1000.0, 0.002), speed=100 * RPM, dt=1e-4)
    fast, ref = run(p, fx, **kw), run(p, fx, engine="reference", **kw)
    assert fast["contact_state"][-1] == CONTACT_BACK
    for k, v in fast.ratios().items():
        assert v == pytest.approx(ref.ratios()[k], abs=1e-6), k
    assert fast.ratios()["back_contact_ratio"] > 0.7


def test_run_failure_is_a_value_error_with_a_clear_message():
    msg = run_failure_message("missed", 0.25, 1, 3.2e-6, 1e-3)
    assert "missed contact event" in msg and "t = 0.25 s" in msg and "apart" in msg
    assert issubclass(RunFailure, ValueError)
    assert 0.0 < G_START < 1e-300


def test_negative_torque_without_back_flank_is_the_model_not_a_failure():
    """No back flank (the paper's model): a negative torque parts the teeth for good. The
    DTE bound applies to compressed flanks only, so this runs and reports it."""
    tr = simulate(GearParams(), Effects(friction="off"), t_end=0.05, torque=-3900.0,
                  speed=100 * RPM, dt=1e-3)
    assert np.all(tr["contact_state"] == CONTACT_SEPARATED)
    assert tr["dte"][-1] < -1e-3


def test_sweep_stores_an_unbounded_point_as_invalid():
    from gearpair.sweep import SweepSettings, run_point

    s = SweepSettings(backlash=1e-5, torque=10000.0, transient_time=0.0,
                      transient_periods=100, kept_periods=16)
    rec = run_point(0, "speed_rpm", 7250.0, s)
    assert rec["status"] == "invalid"
    assert rec["error"].startswith("RunFailure: unbounded response")


# -- the seeded random search ---------------------------------------------------------------
def _scan_module():
    """scripts/contact_scan.py: the scan's case generator, written once for both."""
    spec = importlib.util.spec_from_file_location("contact_scan",
                                                  ROOT / "scripts" / "contact_scan.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_seeded_random_search_finds_no_missed_event():
    """Runs of 1 s drawn with a fixed seed: each either completes with the state matching
    the geometry at every sample (and the guard checking every step inside), or stops with
    an unbounded response; a missed event fails the test. `scripts/contact_scan.py` runs
    the long version (docs/limits.md)."""
    random_case = _scan_module().random_case
    rng = np.random.default_rng(38)
    outcomes = []
    for _ in range(10):
        p, fx, T, W = random_case(rng)
        try:
            run(p, fx, t_end=1.0, torque=T, speed=W, dt=1e-3)
            outcomes.append("ok")
        except RunFailure as e:
            assert "unbounded" in str(e), (p, fx, T, W, e)
            outcomes.append("unbounded")
    assert outcomes.count("ok") >= 7, outcomes


# What the reference engine runs at a cost the suite affords (low speeds: it takes 90-300 s
# per second of simulated time at the search's high speeds; docs/limits.md has the long
# comparison): (params, effects, run, largest ratio difference)
LONGER_AGREEMENT = {
    # the seeded search's run 6 (seed 38: rectangular law, stick-slip friction, 0.86 mm of
    # backlash, damping ratio 0.02, 515 r/min) with its torque reversal moved to 0.05 s:
    # 54 events in 0.1 s, the flanks part, cross the backlash, impact and settle on the
    # back flanks (1 s of the original agrees to 2e-9: docs/limits.md)
    "reversal across the backlash": (
        GearParams(damping_ratio=0.02), Effects(stiffness="rectangular", backlash=8.65e-4),
        dict(t_end=0.1, torque=Step(728.0, -728.0, 0.05), speed=515 * RPM, dt=1e-3), 5e-6),
    # the paper's stick-slip point (Table 1, 3900 N.m, 100 r/min): stick and slip switching
    "stick-slip": (GearParams(), Effects(),
                   dict(t_end=0.04, torque=3900.0, speed=100 * RPM, dt=1e-4), 1e-7),
}


@pytest.mark.parametrize("case", LONGER_AGREEMENT)
def test_reference_engine_agrees_in_the_ratios_over_a_longer_run(case):
    p, fx, kw, tol = LONGER_AGREEMENT[case]
    fast = run(p, fx, **kw).ratios()
    ref = run(p, fx, engine="reference", **kw).ratios()
    for k in ("stick_ratio", "contact_loss_ratio", "back_contact_ratio"):
        assert fast[k] == pytest.approx(ref[k], abs=tol), k
    if case == "stick-slip":
        assert fast["stick_ratio"] > 0.05
    else:  # the agreement is about events: there are some
        assert fast["contact_loss_ratio"] > 0.1 and fast["back_contact_ratio"] > 0.3


def test_reference_engine_agrees_in_the_ratios_of_a_contact_loss_case():
    """The scipy reference engine on a short contact-loss case with backlash: the same
    contact-loss and back-contact ratios as the fast engine."""
    p, fx = GearParams(), Effects(friction="off", backlash=1e-4)
    kw = dict(t_end=0.01, torque=10000.0, speed=5000 * RPM, dt=1e-4)
    fast = run(p, fx, **kw).ratios()
    ref = run(p, fx, engine="reference", **kw).ratios()
    for k in ("contact_loss_ratio", "back_contact_ratio"):
        assert fast[k] == pytest.approx(ref[k], abs=2e-3), k
