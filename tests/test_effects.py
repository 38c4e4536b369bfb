"""Effects switched off or reduced give the analytic or reduced model they should.

Backlash (back-flank contact), the torsional reduction, friction off, separation off and
constant stiffness, each against an analytic limit or the full model it reduces; plus the
rule for a speed input that changes between steps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gearpair import RPM, Effects, GearParams, make_engine
from gearpair.engine import CONTACT_BACK, CONTACT_SEPARATED, CONTACT_STICK
from gearpair.equations import Model
from gearpair.modal import natural_frequencies
from gearpair.results import simulate

P = GearParams()
KM = 4.05e9  # mean mesh stiffness (N/m), Table 1
ENGINES = ("fast", "reference")


def _balance(e, e0) -> tuple[float, float]:
    """Energy residual and scale (J) since a reference point ``e0`` (stored energy there)."""
    E = e.energy()
    res = E["input"] - E["damping"] + E["friction"] + E["parametric"] - (E["stored"] - e0)
    return res, max(abs(E["input"]), E["damping"], abs(e0))


@pytest.mark.parametrize("engine", ENGINES)
def test_back_flank_static_under_negative_torque(engine):
    """Negative torque rests on the back flank: delta = T/(rb1 km) - b, force T/rb1."""
    b = 1e-4
    tr = simulate(P, Effects(stiffness="constant", friction="off", backlash=b), t_end=0.02,
                  torque=-3900.0, speed=100 * RPM, dt=1e-3, engine=engine, rtol=1e-9)
    assert np.all(tr["contact_state"] == CONTACT_BACK)
    np.testing.assert_allclose(tr["dte"], -3900.0 / (P.rb1 * KM) - b, rtol=1e-9)
    np.testing.assert_allclose(tr["mesh_force"], -3900.0 / P.rb1, rtol=1e-8)


def test_without_back_flank_negative_torque_parts_the_teeth():
    """No back flank (the paper): a negative torque parts the teeth for good."""
    tr = simulate(P, Effects(stiffness="constant", friction="off"), t_end=0.01,
                  torque=-3900.0, speed=100 * RPM, dt=1e-3, engine="fast")
    assert np.all(tr["contact_state"] == CONTACT_SEPARATED)
    assert np.all(tr["mesh_force"] == 0.0)


@pytest.mark.parametrize("engine", ENGINES)
def test_torque_reversal_through_the_clearance(engine):
    """Drive flank -> free flight -> back flank impact: energy balances, states as expected,
    and the two engines agree."""
    b = 5e-5
    e = make_engine(P, Effects(backlash=b), engine, rtol=1e-8)
    e.reset(0.0, 3900.0, 100 * RPM)
    e0 = e.energy()["stored"]
    seen = set()
    n_ev = 0
    for k in range(1, 301):
        s = e.advance(k * 2e-4, 3900.0 if k <= 100 else -3900.0, 100 * RPM)
        seen.add(e.outputs().contact_state)
        n_ev += s.n_events
    res, scale = _balance(e, e0)
    assert abs(res) < 1e-5 * scale
    assert {CONTACT_SEPARATED, CONTACT_BACK} <= seen
    o = e.outputs()
    assert o.contact_state == CONTACT_BACK and o.mesh_force < 0.0
    assert n_ev >= 2  # at least: leave the drive flank, hit the back flank
    # the mesh force carries the new torque on the back flank (the 32 Hz mode still rings and
    # friction moments shift it by up to mu: a 10 % band around T/rb1)
    f = []
    for k in range(1, 201):
        e.advance(0.06 + k * 2e-4, -3900.0, 100 * RPM)
        f.append(e.outputs().mesh_force)
    assert np.mean(f) == pytest.approx(-3900.0 / P.rb1, rel=0.1)


def test_reversal_fast_matches_reference():
    b = 5e-5
    out = {}
    for eng in ENGINES:
        e = make_engine(P, Effects(friction="off", backlash=b), eng, rtol=1e-9)
        e.reset(0.0, 3900.0, 100 * RPM)
        dte = []
        for k in range(1, 151):
            e.advance(k * 2e-4, 3900.0 if k <= 50 else -3900.0, 100 * RPM)
            dte.append(e.outputs().dte)
        out[eng] = np.array(dte)
    np.testing.assert_allclose(out["fast"], out["reference"], rtol=0, atol=1e-6 * b)


def test_torsional_modes_are_the_two_dof_analytic_ones():
    """u1, u2 with rigid supports: M = diag(mu1, mu2), K = km g g^T + kr2 on u2."""
    m = Model.build(P, Effects(stiffness="constant", friction="off", dof="torsional"))
    f = natural_frequencies(m, "slip")
    M = np.diag([P.mu1, P.mu2])
    K = KM * np.ones((2, 2)) + np.diag([0.0, P.kr2])
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    np.testing.assert_allclose(f, np.sqrt(lam) / (2 * np.pi), rtol=1e-10)


@pytest.mark.parametrize("engine", ENGINES)
def test_torsional_static_and_no_translation(engine):
    e = make_engine(P, Effects(stiffness="constant", friction="nominal", dof="torsional"),
                    engine, rtol=1e-9)
    e.reset(0.0, 3900.0, 100 * RPM)
    for k in range(1, 21):
        e.advance(k * 1e-3, 3900.0, 100 * RPM)
    y = np.asarray(e.get_state()["y"])
    assert np.all(y[[0, 1, 3, 4, 6, 7, 9, 10]] == 0.0)  # x, y and their rates never move
    # Friction moments shift the static balance; the mesh force stays T/rb1 + friction term
    o = e.outputs()
    assert o.dte == pytest.approx(o.mesh_force / KM, rel=1e-9)
    assert abs(o.mesh_force - 3900.0 / P.rb1) < P.mu * 3900.0 / P.rb1


def test_torsional_matches_six_dof_with_rigid_supports():
    """Supports at the stiffest allowed 1e14 N/m: the 6-DOF model tends to the torsional one
    (support deflections ~F/kb ~ 4e-10 m, 4e-5 of the DTE)."""
    stiff = P.replace(kb1=1e14, kb2=1e14)
    fx = dict(friction="off", stiffness="potential_energy")
    kw = dict(t_end=0.01, torque=3900.0, speed=300 * RPM, dt=2e-4, engine="fast", rtol=1e-9)
    full = simulate(stiff, Effects(**fx), **kw)
    tors = simulate(stiff, Effects(dof="torsional", **fx), **kw)
    scale = np.max(np.abs(tors["dte"]))
    np.testing.assert_allclose(full["dte"], tors["dte"], rtol=0, atol=1e-3 * scale)
    # ... and the support flexibility of Table 1 is visible (the reduction is not a no-op)
    soft = simulate(P, Effects(**fx), **kw)
    assert np.max(np.abs(soft["dte"] - tors["dte"])) > 10 * np.max(np.abs(full["dte"]
                                                                          - tors["dte"]))


def test_friction_off_decouples_x():
    """No friction: nothing forces x1, x2 (Eq. (1)); they stay exactly at rest."""
    e = make_engine(P, Effects(friction="off"), "fast")
    e.reset(0.0, 3900.0, 100 * RPM)
    for k in range(1, 21):
        e.advance(k * 1e-3, 3900.0, 100 * RPM)
    y = np.asarray(e.get_state()["y"])
    assert np.all(y[[0, 3, 6, 9]] == 0.0)
    assert np.max(np.abs(y[[1, 2, 4, 5]])) > 1e-7  # while y and u vibrate


@pytest.mark.parametrize("fx, held", [
    (dict(dof="torsional", stiffness="constant"), [0, 1, 3, 4, 6, 7, 9, 10, 14, 15, 17]),
    (dict(dof="torsional", friction="stick_slip", sliding="full"),
     [0, 1, 3, 4, 6, 7, 9, 10, 17]),
    (dict(), [0, 3, 6, 9, 14, 17]),                 # 6-DOF, time-varying, friction off
    (dict(friction="nominal"), [17]),
    (dict(friction="nominal", stiffness="rectangular"), [15, 17]),
])
def test_switched_off_effects_leave_components_out_of_the_steps(fx, held):
    """The Runge-Kutta steps integrate only the components a scene's effects move: the
    translations the model pins or nothing pushes, the energy quadratures of absent terms
    and the held load-shaft rate stay out (`fast.setup.model_flags`)."""
    from gearpair.fast import N_Y, FastEngine

    e = FastEngine(P, Effects(**{"friction": "off", **fx}))
    assert sorted(set(range(N_Y)) - set(e.integrated.tolist())) == held


def test_friction_off_steps_exactly_as_friction_with_mu_zero():
    """Friction off leaves x1, x2, their rates and the friction work out of the steps;
    regularized friction with mu = 0 integrates them (all zero rates; nominal friction would
    add a step boundary at the pitch point). The two must agree bit for bit: the held
    components are exactly what integrating them gives, and the error control takes the
    same steps."""
    kw = dict(t_end=0.02, torque=3900.0, speed=300 * RPM, dt=1e-3, engine="fast", rtol=1e-8)
    off = simulate(P, Effects(friction="off"), **kw)
    mu0 = simulate(P.replace(mu=0.0), Effects(friction="regularized"), **kw)
    assert np.max(np.abs(off["dte"] - off["dte"].mean())) > 1e-7  # the mesh does vibrate
    for name in ("dte", "mesh_force", "gear1_speed", "output_torque"):
        np.testing.assert_array_equal(off[name], mu0[name], err_msg=name)


def test_nominal_friction_reverses_at_the_pitch_point_without_rejected_steps():
    """The pitch point is a segment boundary, so the step after it must use the new friction
    direction in all its stages. With the direction taken at the boundary itself (nom a
    rounding error from 0) the first stage kept the old one and the error test rejected
    10-21 attempts in a row at every crossing; elsewhere a window has at most 2."""
    p = GearParams()
    speed = 100 * RPM
    worst = {}
    for friction in ("off", "nominal"):
        eng = make_engine(p, Effects(friction=friction), "fast", rtol=1e-8)
        eng.reset(0.0, 3900.0, speed)
        rej = []
        for i in range(1, 401):  # 0.04 s: two pitch-point crossings at 55 Hz mesh frequency
            eng.advance(i * 1e-4, 3900.0, speed)
            rej.append(eng.rejected_steps)
        worst[friction] = max(rej)
    assert worst["off"] <= 3
    assert worst["nominal"] <= worst["off"] + 1


def test_set_state_refuses_motion_a_reduced_model_cannot_carry():
    """A state with x1 moving cannot be continued without friction (x is held at rest):
    ValueError naming the component, and the engine keeps its state."""
    e = make_engine(P, Effects(friction="off"), "fast")
    e.reset(0.0, 3900.0, 100 * RPM)
    before = e.get_state()
    bad = dict(before, y=before["y"].copy())
    bad["y"][6] = 1e-3  # x1' (m/s)
    with pytest.raises(ValueError, match=r"y\[6\].*not simulated"):
        e.set_state(bad)
    np.testing.assert_array_equal(e.get_state()["y"], before["y"])
    e.set_state(before)  # an admissible state is taken


def test_separation_off_is_linear():
    """Separation off: the spring also pulls, so a negative torque gives a negative force
    T/rb1 and delta = T/(rb1 km), like the positive case mirrored."""
    kw = dict(t_end=0.02, speed=100 * RPM, dt=1e-3, engine="fast", rtol=1e-9)
    fx = Effects(stiffness="constant", friction="off", separation=False)
    neg = simulate(P, fx, torque=-3900.0, **kw)
    pos = simulate(P, fx, torque=3900.0, **kw)
    np.testing.assert_allclose(neg["dte"], -pos["dte"], rtol=1e-9)
    np.testing.assert_allclose(neg["mesh_force"][-1], -3900.0 / P.rb1, rtol=1e-8)


@pytest.mark.parametrize("engine", ENGINES)
def test_small_speed_changes_keep_a_stick_with_zero_sliding(engine):
    """A speed input that changes a little every step (a sampled ramp): stuck pairs stay stuck
    and their sliding velocity stays zero; a large jump breaks the stick."""
    e = make_engine(P, Effects(), engine, rtol=1e-8)
    e.reset(0.0, 3900.0, 100 * RPM)
    t = 0.0
    # the first stick: 1 ms steps up to the one that holds a stick (at 15 ms), back to its
    # start, then the 10 us steps (1500 steps through the reference engine otherwise: 30 s)
    while True:
        before = e.get_state()
        s = e.advance(t + 1e-3, 3900.0, 100 * RPM)
        if s.stick_fraction > 0.0 or e.outputs().contact_state == CONTACT_STICK:
            e.set_state(before)
            break
        t += 1e-3
        assert t < 0.05
    while e.outputs().contact_state != CONTACT_STICK:
        t += 1e-5
        e.advance(t, 3900.0, 100 * RPM)
        assert t < 0.05
    w = 100 * RPM
    checked = 0
    for _ in range(5):
        t += 1e-5
        w *= 1.0 + 1e-6
        e.advance(t, 3900.0, w)
        st = e.get_state()
        o = e.outputs()
        if o.contact_state == CONTACT_STICK:
            checked += 1
            m = e.model
            active = np.flatnonzero(np.asarray(st["stuck"]))
            _, xi, s1m, s2m, _ = m.contact(st["s"], active)
            wdir = m.friction_directions(s1m, s2m)
            v = m.sliding_velocity(m.nominal_sliding(s1m, s2m, w), wdir,
                                   np.asarray(st["y"])[6:12])
            assert np.max(np.abs(v)) < 1e-9
    assert checked >= 3
    e.advance(t + 1e-5, 3900.0, 2 * w)
    assert e.outputs().contact_state != CONTACT_STICK
    assert abs(e.outputs().sliding_velocity) > 1e-3


def test_constant_stiffness_static_dte():
    tr = simulate(P, Effects(stiffness="constant", friction="off"), t_end=0.01,
                  torque=3900.0, speed=100 * RPM, dt=1e-3, engine="fast", rtol=1e-10)
    np.testing.assert_allclose(tr["dte"], 3900.0 / (P.rb1 * KM), rtol=1e-9)


def test_invalid_effect_combinations_name_the_option():
    with pytest.raises(ValueError, match="backlash"):
        Effects(backlash=2e-3)
    with pytest.raises(ValueError, match="backlash"):
        Effects(backlash=1e-4, separation=False)
    with pytest.raises(ValueError, match="sliding"):
        Effects(dof="torsional", friction="stick_slip", sliding="paper")
    with pytest.raises(ValueError, match="dof"):
        Effects(dof="lateral")
    assert math.isinf(Model.build(P, Effects()).backlash)
