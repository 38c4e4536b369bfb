"""The exact propagator of the fast engine (`gearpair.fast._piece_lti`).

With friction off and constant or rectangular stiffness the equations have constant
coefficients between switches, and the fast engine steps them with expm(A h) instead of
Dormand-Prince. Checked here: against the scipy reference through separations and back-flank
impacts; Dormand-Prince converging to it as its tolerance tightens; its energy bookkeeping
against the reference's integrated power; and that a quiet piece costs one step.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from gearpair import Effects, GearParams  # noqa: E402
from gearpair.fast import FastEngine  # noqa: E402
from gearpair.reference import ReferenceEngine  # noqa: E402
from gearpair.results import simulate  # noqa: E402

SPEED = 10.472  # rad/s, 100 r/min
REVERSAL = Effects(dof="torsional", stiffness="rectangular", friction="off", backlash=5e-5)


def _steps(engine, t_end, dt, torque):
    out, sums = [], []
    n = int(round(t_end / dt))
    for i in range(1, n + 1):
        sums.append(engine.advance(i * dt, torque, SPEED))
        out.append(engine.outputs())
    return np.array([o.dte for o in out]), np.array([o.mesh_force for o in out]), sums


def test_uses_the_exact_propagator_only_where_coefficients_are_constant():
    mi = lambda fx: FastEngine(None, fx)._md.flag  # noqa: E731
    from gearpair.fast import I_LTI
    assert mi(Effects(friction="off", stiffness="constant"))[I_LTI] == 1
    assert mi(Effects(friction="off", stiffness="rectangular", dof="torsional"))[I_LTI] == 1
    for fx in (Effects(friction="off"), Effects(friction="nominal", stiffness="constant"),
               Effects(friction="regularized", stiffness="constant", sliding="full")):
        assert mi(fx)[I_LTI] == 0
    assert FastEngine(None, Effects(friction="off", stiffness="constant"),
                      exact_lti=False)._md.flag[I_LTI] == 0


def test_matches_reference_through_separation_and_back_flank_impacts():
    """Torque reversed from +500 to -500 N.m at t = 0: the drive flanks separate, the back
    flanks hit and bounce; 6 ms holds several impacts."""
    ref = ReferenceEngine(effects=REVERSAL, rtol=1e-11)
    fast = FastEngine(None, REVERSAL)
    for e in (ref, fast):
        e.reset(0.0, 500.0, SPEED)
    d_r, f_r, s_r = _steps(ref, 0.006, 1e-4, -500.0)
    d_f, f_f, s_f = _steps(fast, 0.006, 1e-4, -500.0)
    n_ev = sum(s.n_events for s in s_r)
    assert n_ev >= 3  # separation, back-flank contact, and more
    assert sum(s.n_events for s in s_f) == n_ev
    assert np.max(np.abs(d_f - d_r)) <= 1e-7 * np.max(np.abs(d_r))
    assert np.max(np.abs(f_f - f_r)) <= 1e-6 * np.max(np.abs(f_r))
    sep_r = np.array([s.separation_fraction for s in s_r])
    sep_f = np.array([s.separation_fraction for s in s_f])
    assert np.max(np.abs(sep_f - sep_r)) <= 1e-6


def test_dormand_prince_converges_to_it():
    """The Runge-Kutta path at tightening rtol approaches the exact propagator (measured
    2e-4, 3e-6, 5e-8 of the DTE scale over 0.2 s of reversals with back-flank impacts)."""
    torque = lambda t: 3900.0 * np.cos(2 * np.pi * 5 * t)  # noqa: E731
    exact = simulate(engine=FastEngine(None, REVERSAL), t_end=0.2, dt=1e-4, torque=torque)
    scale = np.max(np.abs(exact["dte"]))
    assert exact["n_events"].sum() >= 50
    errs = []
    for rtol in (1e-8, 1e-10, 1e-12):
        rk = simulate(engine=FastEngine(None, REVERSAL, rtol=rtol, exact_lti=False), t_end=0.2,
                      dt=1e-4, torque=torque)
        errs.append(np.max(np.abs(rk["dte"] - exact["dte"])) / scale)
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] <= 1e-6


@pytest.mark.parametrize("effects", [Effects(friction="off", stiffness="constant"),
                                     Effects(friction="off", stiffness="rectangular",
                                             dof="torsional")])
def test_energy_terms_match_the_reference_integrals(effects):
    """The exact path books the damping loss as input work minus the stored-energy change;
    the reference integrates the damping power. After a torque step they agree."""
    ref = ReferenceEngine(effects=effects, rtol=1e-11)
    fast = FastEngine(None, effects)
    for e in (ref, fast):
        e.reset(0.0, 3900.0, SPEED)
        for i in range(1, 31):
            e.advance(i * 1e-4, 5000.0, SPEED)
    er, ef = ref.energy(), fast.energy()
    assert er["damping"] > 1e-3
    for k in ("stored", "input", "damping"):
        assert abs(ef[k] - er[k]) <= 1e-7 * abs(er["stored"]) + 1e-6 * abs(er[k]), k


def test_a_quiet_piece_is_one_step():
    """At static equilibrium a whole second is one exact step; after a torque step the
    transient is sampled until it provably cannot move the mesh force by more than rtol, then
    one step ends it (damping ratio 0.2 so that the 32 Hz load-shaft mode dies in 0.5 s)."""
    fx = Effects(dof="torsional", stiffness="constant", friction="off")
    p = GearParams(damping_ratio=0.2)
    e = FastEngine(p, fx)
    e.reset(0.0, 3900.0, SPEED)
    d0 = e.outputs().dte
    s = e.advance(1.0, 3900.0, SPEED)
    assert s.n_steps == 1
    assert abs(e.outputs().dte - d0) <= 1e-12 * d0
    s = e.advance(3.0, 5000.0, SPEED)
    n_sampled = 2.0 / e.sample_spacing
    assert 1 < s.n_steps < 0.5 * n_sampled
    # the end state is the static deflection under 5000 N.m
    e2 = FastEngine(p, fx)
    e2.reset(0.0, 5000.0, SPEED)
    assert abs(e.outputs().dte - e2.outputs().dte) <= 1e-7 * e2.outputs().dte
    # and Dormand-Prince agrees over the transient
    rk = FastEngine(p, fx, exact_lti=False, rtol=1e-11)
    ex = FastEngine(p, fx)
    for eng in (rk, ex):
        eng.reset(0.0, 3900.0, SPEED)
    d_rk, _, _ = _steps(rk, 0.02, 1e-3, 5000.0)
    d_ex, _, _ = _steps(ex, 0.02, 1e-3, 5000.0)
    assert np.max(np.abs(d_rk - d_ex)) <= 1e-8 * np.max(np.abs(d_ex))
