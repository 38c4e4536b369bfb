"""The model's set-up compiled (`gearpair.fast.setup`): one function from gear data and
choices to the fast engine's records, called from Python and from C at its address.

Tiers: closed forms of the geometry and the flat laws; the step bound against the modal
analysis; the same bits through the C address as through numba's dispatcher; the checks
that refuse gear data that cannot mesh. The bits of whole runs are held by the golden files.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest

from gearpair import Effects, GearParams
from gearpair.effects import StiffnessSpec
from gearpair.fast import setup as S
from gearpair.fast.engine import FastEngine, FastOptions
from gearpair.fast.layout import I_KIND, I_NTAB, KIND_CUBIC, P_KMEAN, P_L, P_MAXSTEP
from gearpair.fast.native import compiled
from gearpair.modal import natural_frequencies

# own gear data with Table 1's bodies: the set-up's arithmetic is what is tested here
pytestmark = pytest.mark.filterwarnings("ignore::gearpair.geometry.GearDataWarning")

GEARS = [GearParams(), GearParams(module=4e-3, z1=25, z2=60),
         GearParams(z1=17, z2=90, addendum_coef=1.2, pressure_angle=math.radians(25)),
         GearParams(dedendum_coef=1.0, z1=40, z2=41)]


@pytest.mark.parametrize("p", GEARS)
def test_geometry_follows_the_closed_forms(p):
    geo = S.geometry_vector(p)
    g = dict(zip(S.GEO_NAMES, geo, strict=True))
    m, a0 = p.module, p.pressure_angle
    rb1, rb2 = m * p.z1 * math.cos(a0) / 2, m * p.z2 * math.cos(a0) / 2
    ra1, ra2 = m * p.z1 / 2 + p.addendum_coef * m, m * p.z2 / 2 + p.addendum_coef * m
    s1s2 = m * (p.z1 + p.z2) / 2 * math.sin(a0)
    s1a = s1s2 - math.sqrt(ra2 ** 2 - rb2 ** 2)
    s1e = math.sqrt(ra1 ** 2 - rb1 ** 2)
    pb = math.pi * m * math.cos(a0)
    for name, want in (("rb1", rb1), ("rb2", rb2), ("s1s2", s1s2), ("s1a", s1a),
                       ("s1e", s1e), ("base_pitch", pb), ("s1p", rb1 * math.tan(a0)),
                       ("contact_ratio", (s1e - s1a) / pb)):
        assert g[name] == pytest.approx(want, rel=1e-14), name
    assert g["n_pairs"] == math.ceil((s1e - s1a) / pb)


@pytest.mark.parametrize("kind", ["constant", "rectangular"])
def test_flat_laws_keep_the_mean(kind):
    p = GearParams()
    md = S.run_setup(p, stiffness=StiffnessSpec(kind)).md
    eps = S.geometry_vector(p)[S.GEO_EPS]
    k0 = p.km_mean if kind == "constant" else p.km_mean / eps
    assert md.k_coef.tolist() == [k0, k0] and md.k_slope.tolist() == [0.0]
    assert md.xi_knots.tolist() == [0.0, md.par[P_L]] and md.par[P_KMEAN] == p.km_mean


def test_the_spline_law_has_the_mean_it_is_scaled_to():
    """The spline's exact mean equals km_mean scaled; unscaled, it is the mean of the raw
    potential-energy law (a fine trapezoid of the compiled compliances) within 1e-6."""
    p = GearParams()
    scaled = S.run_setup(p).md
    raw = S.run_setup(p, stiffness=StiffnessSpec(scale_to_mean=False)).md
    assert scaled.flag[I_KIND] == KIND_CUBIC and scaled.flag[I_NTAB] == S.N_SPLINE
    assert scaled.par[P_KMEAN] == p.km_mean
    geo = S.geometry_vector(p)
    xi = np.linspace(0.0, raw.par[P_L], 4001)
    c = sum(S.tooth_compliances(p, xi, gear) for gear in (1, 2)).sum(axis=0)
    k = 1.0 / (c + 4.0 * (1.0 - p.poisson ** 2) / (math.pi * p.youngs_modulus * p.face_width))
    mean = float(np.sum(0.5 * (k[1:] + k[:-1]) * np.diff(xi))) / geo[S.GEO_PB]
    assert raw.par[P_KMEAN] == pytest.approx(mean, rel=1e-6)
    ratio = scaled.k_coef / raw.k_coef  # one factor on every coefficient
    assert np.allclose(ratio, p.km_mean / raw.par[P_KMEAN], rtol=1e-15, atol=0)


@pytest.mark.parametrize("fx", [Effects(), Effects(dof="torsional", sliding="full"),
                                Effects(friction="off", stiffness="rectangular")])
def test_the_step_bound_is_half_the_period_of_the_highest_slip_mode(fx):
    e = FastEngine(GearParams(), fx)
    top = natural_frequencies(e.model, "slip")[-1]
    assert e.max_step == 0.5 / float(top)  # the same eigen-solver, the same bits


def test_the_c_address_gives_the_bits_of_the_dispatcher():
    """`setup_entry` called through its C address (as the FMU's C layer will) fills the
    same arrays bit for bit."""
    p, fx = GearParams(module=4e-3, z1=25, z2=60), Effects(backlash=1e-4)
    want = S.run_setup(p, fx, rtol=1e-7, options=FastOptions(method="dp5"))
    _, address = compiled(S.setup_entry)
    call = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_int64)(address)
    arrays = [S.gear_vector(p), S.choice_vector(p, fx, rtol=1e-7,
                                                options=FastOptions(method="dp5")),
              np.zeros(2), np.zeros(2)]
    arrays += [np.zeros(n, dtype=np.float64 if k == "f" else np.int64)
               for _, k, n in S.SETUP_ARRAYS[4:]]
    words = np.array([w for a in arrays for w in (a.ctypes.data, a.shape[0])], dtype=np.int64)
    assert call(int(words.ctypes.data)) == S.SETUP_OK
    geo, par, flag, atol, xi, kc, ks = arrays[4:11]
    assert np.array_equal(geo, want.geo)
    for a, b in ((par, want.md.par), (flag, want.md.flag), (atol, want.md.atol)):
        assert np.array_equal(a, b)
    n = len(want.md.xi_knots)
    assert np.array_equal(xi[:n], want.md.xi_knots)
    assert np.array_equal(kc[:len(want.md.k_coef)], want.md.k_coef)
    assert par[P_MAXSTEP] > 0


def test_gear_data_that_cannot_mesh_are_refused_with_the_reason():
    with pytest.raises(ValueError, match="contact ratio 0.9"):
        S.run_setup(GearParams(addendum_coef=0.5))
    with pytest.raises(ValueError, match="interference"):
        S.run_setup(GearParams(z1=12, z2=12, addendum_coef=1.5, pressure_angle=math.radians(10)))


@pytest.mark.parametrize("p", GEARS)
@pytest.mark.parametrize("fx, torque", [(Effects(), 3900.0),
                                        (Effects(dof="torsional", sliding="full"), 2000.0),
                                        (Effects(friction="off", backlash=1e-4), -1500.0),
                                        (Effects(stiffness="rectangular"), -800.0)])
def test_the_compiled_reset_rests_where_the_model_says(p, fx, torque):
    """`start.reset_state` (what `FastEngine.reset` and the FMU's C layer run) puts the
    gears in the static equilibrium of `Model.static_deflection` bit for bit, with the
    contact code of `Model.contact_code`."""
    from gearpair.fast.layout import J_NPREV, J_SEP

    e = FastEngine(p, fx)
    e.reset(0.25, torque, 10.0)
    m = e.model
    active, _, _, _, k = m.contact(0.0)
    q = m.static_deflection(torque, float(k.sum()))
    assert np.array_equal(e._hs.y[:6], q) and not e._hs.y[6:].any()
    delta = q[1] - q[4] + q[2] + q[5]
    assert e._hs.mode[J_SEP] == m.contact_code(delta)
    assert e._hs.mode[J_NPREV] == len(active)
    assert e.time == 0.25 and e._last is None


def test_initialization_through_the_c_address_shows_the_static_equilibrium():
    """`native.init_entry` called at its C address leaves in the step block the outputs the
    Python API gives after the same reset, and the figures of an empty step."""
    from gearpair.engine import StepSummary
    from gearpair.fast.native import init_entry
    from gearpair.stepblock import STEP_DONE, STEP_RECORD, X_REC, X_SPEED, X_TCHK, X_TORQUE

    p, fx = GearParams(module=4e-3, z1=25, z2=60), Effects(backlash=1e-4)
    e = FastEngine(p, fx)
    e.reset(0.1, -700.0, 30.0)
    o = e.outputs()
    want = (o.dte, o.mesh_force, o.friction_force, o.contact_state, o.output_torque,
            o.input_torque_reaction, o.input_torque, o.gear1_speed, o.gear2_speed,
            o.sliding_velocity) + tuple(StepSummary.at_instant(o))[2:]
    c = FastEngine(p, fx)
    x = c.block
    x[X_TCHK], x[X_TORQUE], x[X_SPEED] = 0.1, -700.0, 30.0
    _, address = compiled(init_entry)
    call = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_int64)(address)
    assert call(c._table_address) == STEP_DONE
    got = x[X_REC:X_REC + len(STEP_RECORD)]
    assert np.array_equal(got, np.array(want, dtype=float))
    assert np.array_equal(c._state, e._state, equal_nan=True)
    x[X_TORQUE] = 2e6  # out of range: refused, nothing changed
    assert call(c._table_address) != STEP_DONE
    assert np.array_equal(c._state, e._state, equal_nan=True)
