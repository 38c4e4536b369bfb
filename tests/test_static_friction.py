"""Static and kinetic friction (`Effects.mu_static`, `Effects.stribeck_velocity`).

``mu`` stays the kinetic coefficient; ``mu_static`` bounds the static friction in the stick
test of Eq. (14); the optional Stribeck curve gives the sliding coefficient
``mu + (mu_static - mu) exp(-(|v|/v_s)^2)``. Both engines carry the effect; the physics is
tested on each, and the fast engine against the reference. Runs are short (two mesh periods at the
stick-slip point: 100 r/min, 3900 N.m, Table 1 data with mu = 0.03) and shared between tests.
"""

from __future__ import annotations

import functools
import importlib.util
import math

import numpy as np
import pytest

from gearpair import RPM, Effects, GearParams, make_engine
from gearpair.engine import CONTACT_SLIP, CONTACT_STICK
from gearpair.equations import Model, check_friction_coefficients, sliding_coefficient
from gearpair.scenes import SceneError, fmu_start_values, load_scene

MU = 0.03
P = GearParams(mu=MU)
TORQUE, SPEED = 3900.0, 100 * RPM
TM = 2 * math.pi / (P.z1 * SPEED)  # mesh period (s)
# mesh periods per run: the first holds the start from static equilibrium, the second is
# measured (stick and slip in each run; with three the extremes of friction/normal force in
# stick and slip were the same, all in the first two)
N_PER = 2
N_SUB = 24       # recorded steps per mesh period (off the pair entries: phase 0.999)
RTOL = 1e-7


ENGINES = ["reference", pytest.param("fast", marks=pytest.mark.skipif(
    not importlib.util.find_spec("numba"), reason="the fast engine needs numba"))]


@functools.cache
def run(mu_static=None, stribeck=None, sliding="paper", engine="reference") -> dict:
    """A run from static equilibrium; outputs, step figures and energies per step."""
    fx = Effects(mu_static=mu_static, stribeck_velocity=stribeck, sliding=sliding)
    e = make_engine(P, fx, engine, rtol=RTOL)
    e.reset(0.0, TORQUE, SPEED)
    e0 = e.energy()
    t = (np.arange(N_PER * N_SUB) + 0.999) * TM / N_SUB
    rec = {k: np.zeros(len(t)) for k in ("friction_force", "mesh_force", "contact_state",
                                          "dte", "stick_fraction", "residual", "scale")}
    states = []
    for i, te in enumerate(t):
        s = e.advance(te, TORQUE, SPEED)
        o = e.outputs()
        for k in ("friction_force", "mesh_force", "contact_state", "dte"):
            rec[k][i] = getattr(o, k)
        rec["stick_fraction"][i] = s.stick_fraction
        E = e.energy()
        rec["residual"][i] = E["stored"] - e0["stored"] - (
            E["input"] - E["damping"] + E["friction"] + E["parametric"])
        rec["scale"][i] = max(E["stored"], e0["stored"]) + abs(E["input"]) + E["damping"] \
            + abs(E["friction"]) + abs(E["parametric"])
    states.append(e.get_state())
    rec["t"] = t
    rec["state"] = states[-1]
    return rec


def stick_ratio(rec: dict) -> float:
    """Stick ratio after the first mesh period (past the start from static equilibrium)."""
    return float(np.mean(rec["stick_fraction"][N_SUB:]))


# -- the sliding coefficient ----------------------------------------------------------------------
def test_sliding_coefficient_limits():
    mu, ms, vs = 0.02, 0.05, 0.01
    assert sliding_coefficient(mu, ms, vs, 0.0) == ms
    v = np.array([-1e-9, 1e-9])
    np.testing.assert_allclose(sliding_coefficient(mu, ms, vs, v), ms, rtol=1e-12)
    v = np.array([-0.2, 0.2, 1.0])  # |v| >= 20 v_s: exp(-400) is below every rounding
    assert np.all(sliding_coefficient(mu, ms, vs, v) == mu)
    assert sliding_coefficient(mu, ms, vs, vs) == pytest.approx(mu + (ms - mu) / math.e,
                                                                rel=1e-14)
    v = np.linspace(0.0, 0.05, 101)
    c = sliding_coefficient(mu, ms, vs, v)
    assert np.all(np.diff(c) < 0.0)  # falls monotonically from mu_static to mu
    np.testing.assert_array_equal(c, sliding_coefficient(mu, ms, vs, -v))  # even in v
    assert sliding_coefficient(mu, ms, 0.0, 0.3) == mu  # no Stribeck: the kinetic mu


# -- validation -----------------------------------------------------------------------------------
@pytest.mark.parametrize("kw, words", [
    (dict(mu_static=-0.01), ("mu_static", "[0, 1]")),
    (dict(mu_static=1.5), ("mu_static", "[0, 1]")),
    (dict(mu_static=math.nan), ("mu_static", "[0, 1]")),
    (dict(mu_static=True), ("mu_static", "[0, 1]")),
    (dict(stribeck_velocity=-1e-3), ("stribeck_velocity", "(0, 1] m/s")),
    (dict(stribeck_velocity=2.0), ("stribeck_velocity", "(0, 1] m/s")),
    (dict(stribeck_velocity=math.inf), ("stribeck_velocity", "(0, 1] m/s")),
    (dict(stribeck_velocity=0.01, friction="nominal"), ("stribeck_velocity", "stick_slip")),
    (dict(stribeck_velocity=0.01, friction="off"), ("stribeck_velocity", "regularized")),
])
def test_effects_refuse_naming_the_parameter_and_range(kw, words):
    with pytest.raises(ValueError) as exc:
        Effects(**kw)
    assert all(w in str(exc.value) for w in words), str(exc.value)


@pytest.mark.parametrize("kw, words", [
    (dict(mu_static=0.02), ("mu_static", "[mu, 1] = [0.03, 1]")),
    (dict(mu_static=0.0), ("mu_static", "[mu, 1]")),
    (dict(mu_static=0.06, friction="nominal"), ("mu_static", "'nominal'")),
    (dict(mu_static=0.06, friction="off"), ("mu_static", "'off'")),
    (dict(mu_static=0.06, friction="regularized"), ("mu_static", "stribeck_velocity")),
])
def test_model_refuses_coefficients_that_do_not_fit(kw, words):
    with pytest.raises(ValueError) as exc:
        Model.build(P, Effects(**kw))
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_defaults_and_what_is_accepted():
    assert Effects(stribeck_velocity=0.0) == Effects()  # 0 is "off", as None
    assert Effects(stribeck_velocity=0.0).stribeck_velocity is None
    assert Model.build(P, Effects()).mu_static == MU
    assert Model.build(P, Effects(mu_static=0.045)).mu_static == 0.045
    assert Model.build(P, Effects(mu_static=MU, friction="nominal")).mu_static == MU
    assert check_friction_coefficients(P, Effects(friction="regularized", mu_static=0.06,
                                                  stribeck_velocity=0.01)) == 0.06


# -- physics (both engines) ------------------------------------------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
def test_mu_static_equal_to_mu_is_bit_identical(engine):
    """Writing mu_static = mu (with or without a Stribeck curve, which then has no gap to
    decay over) changes no bit of the run with the option absent."""
    base = run(engine=engine)
    for other in (run(MU, engine=engine), run(MU, 0.01, engine=engine)):
        np.testing.assert_array_equal(other["state"]["y"], base["state"]["y"])
        for k in ("friction_force", "mesh_force", "dte", "stick_fraction", "contact_state"):
            np.testing.assert_array_equal(other[k], base[k])
    assert stick_ratio(base) > 0.05  # the point does stick, so the stick test was exercised


@pytest.mark.parametrize("engine", ENGINES)
def test_stick_ratio_rises_with_mu_static(engine):
    ratios = [stick_ratio(run(ms, engine=engine)) for ms in (None, 1.5 * MU, 2.0 * MU)]
    assert ratios[0] > 0.05
    assert ratios[0] < ratios[1] < ratios[2], ratios


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("stribeck, sliding", [(None, "paper"), (0.01, "paper"),
                                               (0.01, "full")])
def test_energy_balance_and_friction_bounds(stribeck, sliding, engine):
    """The energy quadratures close; static friction goes beyond mu N (up to mu_static N)
    while sliding friction stays within mu N without a Stribeck curve."""
    rec = run(2.0 * MU, stribeck, sliding, engine)
    assert np.max(np.abs(rec["residual"]) / rec["scale"]) <= 50 * RTOL
    cs, ff, fm = rec["contact_state"], np.abs(rec["friction_force"]), np.abs(rec["mesh_force"])
    assert np.all(ff <= 2.0 * MU * fm * (1 + 1e-9))
    stick, slip = cs == CONTACT_STICK, cs == CONTACT_SLIP
    assert stick.any() and slip.any()
    assert np.max(ff[stick] / fm[stick]) > 1.1 * MU  # static friction beyond the kinetic mu
    if stribeck is None:
        assert np.all(ff[slip] <= MU * fm[slip] * (1 + 1e-9))


# -- the fast engine against the reference ---------------------------------------------------------
@pytest.mark.parametrize("stribeck, sliding", [(None, "paper"), (0.01, "paper"),
                                               (0.01, "full")])
def test_fast_engine_agrees_with_the_reference(stribeck, sliding):
    """The same switches at the same instants: stick fractions and DTE as the reference's
    (to the tolerances' level), with mu_static = 2 mu."""
    pytest.importorskip("numba")
    ref = run(2.0 * MU, stribeck, sliding)
    fast = run(2.0 * MU, stribeck, sliding, "fast")
    np.testing.assert_array_equal(fast["contact_state"], ref["contact_state"])
    assert np.max(np.abs(fast["stick_fraction"] - ref["stick_fraction"])) <= 1e-4
    scale = np.max(np.abs(ref["dte"]))
    assert np.max(np.abs(fast["dte"] - ref["dte"])) <= 1e-5 * scale


# -- scenes ---------------------------------------------------------------------------------------
def _scene(tmp_path, effects: str):
    path = tmp_path / "s.toml"
    path.write_text(f"[gear]\nmu = {MU}\n[effects]\n{effects}\n")
    return load_scene(path)


def test_scene_keys_and_errors(tmp_path):
    sc = _scene(tmp_path, "mu_static = 0.045\nstribeck_velocity = 0.01")
    assert (sc.effects.mu_static, sc.effects.stribeck_velocity) == (0.045, 0.01)
    assert _scene(tmp_path, "stribeck_velocity = 0").effects == Effects()
    with pytest.raises(SceneError, match=r"\[effects\] mu_static = 0.02 is out of range; "
                                         r"allowed \[mu, 1\]"):
        _scene(tmp_path, "mu_static = 0.02")
    with pytest.raises(SceneError, match=r"\[effects\] stribeck_velocity = 5"):
        _scene(tmp_path, "stribeck_velocity = 5")


def test_scene_start_values_for_the_fmu(tmp_path):
    """The scene's values reach the FMU's parameters; absent ones keep the FMU's start 0."""
    pytest.importorskip("pythonfmu")
    import importlib.util
    from pathlib import Path
    from types import SimpleNamespace

    import gearpair

    src = Path(__file__).resolve().parents[1] / "fmu_src" / "GearPair.py"
    spec = importlib.util.spec_from_file_location("_gearpair_slave_src", src)
    slave = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(slave)
    variables = {v["name"]: SimpleNamespace(description=v["description"])
                 for v in slave.interface(gearpair)}
    names = ("mu_static", "stribeck_velocity")
    sc = _scene(tmp_path, "mu_static = 0.045\nstribeck_velocity = 0.01")
    start = fmu_start_values(sc, variables)
    assert (start["mu_static"], start["stribeck_velocity"]) == (0.045, 0.01)
    plain = fmu_start_values(_scene(tmp_path, ""), variables)
    assert not set(names) & set(plain)  # not given: the FMU's start value 0 ("equal to mu")
    for n in names:
        del variables[n]
    with pytest.raises(SceneError, match="mu_static"):
        fmu_start_values(sc, variables)
