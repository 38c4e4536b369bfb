"""Property-based tests (hypothesis) of the physics core over physically valid ranges.

Gear data are drawn around Table 1 (masses and inertias within a factor of about 3, tooth
numbers 20-40 / 40-100, support stiffnesses 1e7-1e9 and 1e9-1e12 N/m, damping ratio
0.01-0.1, mu 0-0.3, mean mesh stiffness 1e9-1e10 N/m), inputs from 100 N.m to 10 kN.m and
1 to 400 rad/s, and every friction law, stiffness law, sliding variant, stick tie and
separation switch. Each example runs a short horizon (a few mesh periods at most) through
the fast engine. Examples are derandomized (the same examples on every run, so CI is
reproducible and the budget is fixed); ``max_examples`` is kept small for the CI budget.

Negative and zero speeds are left to tests/test_hard_cases.py (two known bugs there).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")
hypothesis = pytest.importorskip("hypothesis")

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from test_hard_cases import (  # noqa: E402
    RTOL,
    Case,
    build_engine,
    check_engine_run,
    drive,
    schedule,
    uniform,
)

from gearpair import Effects, GearParams, StiffnessSpec  # noqa: E402
from gearpair.fast import FastEngine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

# The strategies draw masses, inertias and tooth numbers independently (the physics must hold
# for any valid data), so some examples keep a Table 1 body with other teeth: the warning for
# that user slip is expected here, and only here; any other warning still shows.
pytestmark = pytest.mark.filterwarnings(
    r"ignore:.*are Table 1's values, but:gearpair.geometry.GearDataWarning")

SETTINGS = settings(max_examples=40, deadline=None, derandomize=True, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def log_floats(lo: float, hi: float):
    """Log-uniform floats in [lo, hi]."""
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda x: float(10.0 ** x))


@st.composite
def gear_params(draw) -> GearParams:
    return GearParams(
        m1=draw(st.floats(6.0, 50.0)), m2=draw(st.floats(35.0, 300.0)),
        J1=draw(st.floats(0.05, 0.5)), J2=draw(st.floats(1.5, 15.0)),
        z1=draw(st.integers(20, 40)), z2=draw(st.integers(40, 100)),
        kb1=draw(log_floats(1e7, 1e9)), kb2=draw(log_floats(1e9, 1e12)),
        kr2=draw(log_floats(1e6, 1e8)), damping_ratio=draw(st.floats(0.01, 0.1)),
        mu=draw(st.floats(0.0, 0.3)), km_mean=draw(log_floats(1e9, 1e10)))


@st.composite
def effects(draw, friction=("off", "nominal", "regularized", "stick_slip")) -> Effects:
    return Effects(
        stiffness=StiffnessSpec(draw(st.sampled_from(("constant", "rectangular",
                                                       "potential_energy")))),
        separation=draw(st.booleans()),
        friction=draw(st.sampled_from(friction)),
        v_eps=draw(log_floats(1e-3, 1e-2)),
        sliding=draw(st.sampled_from(("paper", "full"))),
        stick_tie=draw(st.sampled_from(("exact", "paper"))))


torques = log_floats(100.0, 1e4)
speeds = log_floats(1.0, 400.0)


def horizon(p: GearParams, speed: float) -> tuple[float, float]:
    """(t_end, h): 2.3 mesh periods, at most 20 ms, in 25 steps. Not a whole number of
    periods: a communication point on a pair entry is a known bug (test_hard_cases)."""
    period = 2.0 * math.pi / (p.z1 * speed)
    t_end = min(2.3 * period, 0.02)
    return t_end, t_end / 25.0


@settings(SETTINGS, max_examples=100)
@given(p=gear_params(), fx=effects(), torque=torques, speed=speeds)
def test_invariants_hold_everywhere(p, fx, torque, speed):
    """Finite outputs, energy balance, Coulomb cone, stuck -> v = 0, slip along v,
    separated -> no force, the event-count rule: on every step of every example."""
    t_end, h = horizon(p, speed)
    case = Case("property", schedule(uniform(h, t_end), torque, speed), p, fx)
    run = drive(build_engine(p, fx, RTOL), case)
    check_engine_run(run)
    # the static start leaves the mean mesh force near Tr/rb1 (no blow-up, no collapse)
    assert 0.0 <= np.mean(run.out["mesh_force"]) <= 3.0 * torque / p.rb1


@SETTINGS
@given(p=gear_params(), fx=effects(friction=("off", "nominal")), torque=torques,
       speed=speeds, alpha=log_floats(0.1, 10.0))
def test_response_is_homogeneous_in_the_torque(p, fx, torque, speed, alpha):
    """Without a law that reads the sliding velocity, every force (mesh, support, Coulomb
    friction mu N) is homogeneous of degree one in the deflections and starts from the static
    deflection, which is linear in the torque: the whole response scales with the torque,
    separation included."""
    t_end, h = horizon(p, speed)
    ends = uniform(h, t_end)
    runs = []
    for T in (torque, alpha * torque):
        e = FastEngine(p, fx, rtol=1e-9)
        e.reset(0.0, T, speed)
        rows = []
        for te in ends:
            s = e.advance(te, T, speed)
            o = e.outputs()
            rows.append((o.dte, o.mesh_force, o.friction_force, s.separation_fraction))
        runs.append(np.array(rows))
    a, b = runs
    for k in range(3):
        scale = max(np.max(np.abs(a[:, k])), 1e-300)
        assert np.max(np.abs(b[:, k] - alpha * a[:, k])) <= 1e-5 * alpha * scale
    assert np.allclose(a[:, 3], b[:, 3], atol=1e-3)


@SETTINGS
@given(p=gear_params(), fx=effects(), torque=torques, speed=speeds,
       cut=st.integers(1, 20))
def test_state_round_trip_continues_bit_for_bit(p, fx, torque, speed, cut):
    """get_state / set_state into a fresh engine: the continuation is identical."""
    t_end, h = horizon(p, speed)
    ends = uniform(h, t_end)
    a = FastEngine(p, fx, rtol=RTOL)
    a.reset(0.0, torque, speed)
    for te in ends[:cut]:
        a.advance(te, torque, speed)
    b = FastEngine(p, fx, rtol=RTOL)
    b.set_state(a.get_state())
    assert b.outputs() == a.outputs()
    for te in ends[cut:]:
        assert a.advance(te, torque, speed) == b.advance(te, torque, speed)
        assert a.outputs() == b.outputs()
    assert a.energy() == b.energy()


@SETTINGS
@given(p=gear_params(), fx=effects(friction=("off", "nominal", "regularized")),
       torque=torques, speed=speeds, data=st.data())
def test_end_state_does_not_depend_on_the_communication_steps(p, fx, torque, speed, data):
    """Constant inputs: one long step and the same interval cut into random steps (1 us
    and up) end in the same state, to the integrator's accuracy."""
    t_end, _ = horizon(p, speed)
    cuts = sorted(set(data.draw(st.lists(st.floats(1e-6, t_end - 1e-6), min_size=1,
                                         max_size=12))))
    ends = [c for c in cuts if c > 1e-6] + [t_end]
    outs = []
    for grid in ([t_end], ends):
        e = FastEngine(p, fx, rtol=1e-9)
        e.reset(0.0, torque, speed)
        for te in grid:
            e.advance(te, torque, speed)
        assert e.time == t_end
        outs.append(e.outputs())
    one, many = outs
    scale = abs(torque / (p.rb1 * p.km_mean))  # the static DTE
    assert abs(one.dte - many.dte) <= 1e-5 * scale
    assert abs(one.mesh_force - many.mesh_force) <= 1e-5 * torque / p.rb1 * 2.0
    assert one.contact_state == many.contact_state


@SETTINGS
@given(p=gear_params(), torque=torques, speed=speeds, separation=st.booleans())
def test_static_equilibrium_is_exact_without_excitation(p, torque, speed, separation):
    """Constant total mesh stiffness and no friction: nothing excites the pair, so the
    static equilibrium of Eqs. (4)-(6) holds at every step: delta = Tr/(rb1 km), mesh force
    Tr/rb1, output torque Tr z2/z1, for any gear data and speed."""
    fx = Effects(stiffness="constant", friction="off", separation=separation)
    e = FastEngine(p, fx, rtol=RTOL)
    e.reset(0.0, torque, speed)
    t_end, h = horizon(p, speed)
    # the integrator may wander by its absolute tolerance (rtol x 1e-5 m on the deflections)
    # around the equilibrium; the smallest static DTE drawn is ~2e-10 m
    atol = 10.0 * RTOL * 1e-5
    for te in uniform(h, t_end):
        s = e.advance(te, torque, speed)
        o = e.outputs()
        dte = torque / (p.rb1 * p.km_mean)
        assert o.dte == pytest.approx(dte, rel=1e-6, abs=atol)
        assert o.mesh_force == pytest.approx(torque / p.rb1, rel=1e-6 + atol / dte)
        assert o.output_torque == pytest.approx(torque * p.z2 / p.z1, rel=1e-6)
        assert o.friction_force == 0.0 and o.contact_state == 1
        assert s.n_events == 0 and s.separation_fraction == 0.0


# -- the expected warnings are filtered where they are expected ----------------------------
def test_property_tests_expect_their_table1_body_warnings_and_no_other(tmp_path):
    """With GearDataWarning made an error, the property tests still pass: the one they
    expect (Table 1 bodies with drawn tooth numbers) is filtered in that file, so a new
    warning there would stand out instead of drowning among twenty. The child run leaves
    this test out: it lives in the file it runs and would otherwise start itself again."""
    import subprocess
    import sys

    pytest.importorskip("hypothesis")
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-W",
         "error::gearpair.geometry.GearDataWarning", "-k", "not table1_body_warnings",
         str(ROOT / "tests" / "test_properties.py")],
        cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert "warning" not in proc.stdout.splitlines()[-1]
