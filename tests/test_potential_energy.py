"""Tests of the potential-energy tooth-pair stiffness (gearpair.potential_energy)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from gearpair import potential_energy as pe
from gearpair.geometry import Geometry
from gearpair.params import GearParams


@pytest.fixture(scope="module")
def table1():
    p = GearParams()
    return p, Geometry.from_params(p)


def _xi(g: Geometry, n: int = 401) -> np.ndarray:
    return np.linspace(0.0, g.path_length, n)


def test_pitch_point_stiffness_is_of_published_order(table1):
    p, g = table1
    k = float(pe.pair_stiffness_raw(p, g, np.array([g.xi_pitch]))[0])
    # ISO 6336-1 gives a single-pair stiffness c' of about 14 N/(mm um) = 1.4e10 N/m per metre
    # of face width for solid steel spur gears; published potential-energy curves of steel
    # spur pairs lie between about 1e10 and 3e10 N/m per metre. With b = 0.2 m that is
    # 2e9..6e9 N/m; the bound 1.5e9..6e9 also allows for this pair's thin rims.
    # (This implementation gives 2.81e9 N/m, i.e. 1.41e10 N/m per metre.)
    assert 1.5e9 < k < 6e9
    assert 1e10 < k / p.face_width < 3e10


def test_mean_mesh_stiffness_is_near_table1(table1):
    p, g = table1
    # The time mean of the mesh stiffness is the contact ratio times the mean single-pair
    # stiffness over the path. Table 1 gives 4.05e9 N/m (from the paper's FE model); the
    # unscaled analytic curve must land within 30 % of it, not orders of magnitude away.
    kmean = g.contact_ratio * float(np.mean(pe.pair_stiffness_raw(p, g, _xi(g, 2001))))
    assert 0.7 * p.km_mean < kmean < 1.3 * p.km_mean


def test_positive_finite_and_smooth(table1):
    p, g = table1
    xi = _xi(g)
    k = pe.pair_stiffness_raw(p, g, xi)
    assert k.shape == xi.shape
    assert np.all(np.isfinite(k)) and np.all(k > 0)
    # Smooth: the second difference on a 401-point grid is tiny compared with k (a kink or
    # jump of even 1 % would show as a second difference of ~1e-2 k).
    d2 = np.abs(np.diff(k, 2))
    assert np.max(d2) < 1e-3 * np.max(k)
    # One maximum: rises, then falls (no wiggles).
    d1 = np.diff(k)
    i = int(np.argmax(k))
    assert np.all(d1[: i - 1] > 0) and np.all(d1[i + 1 :] < 0)


def test_bending_compliance_grows_toward_each_tip(table1):
    p, g = table1
    xi = _xi(g)
    b1 = pe.tooth_compliances(p, g, xi, 1)["bending"]
    b2 = pe.tooth_compliances(p, g, xi, 2)["bending"]
    assert np.all(np.diff(b1) > 0)  # gear 1's tip is at xi = L
    assert np.all(np.diff(b2) < 0)  # gear 2's tip is at xi = 0
    # Loaded at its tip a tooth is far softer than loaded near its root.
    assert b1[-1] > 20 * b1[0] and b2[0] > 20 * b2[-1]


def test_pair_stiffness_is_largest_in_the_middle(table1):
    p, g = table1
    xi = _xi(g)
    k = pe.pair_stiffness_raw(p, g, xi)
    L = g.path_length
    assert L / 3 < xi[np.argmax(k)] < 2 * L / 3
    assert k.max() > 1.3 * max(k[0], k[-1])


def test_equal_gears_give_a_symmetric_curve():
    # With z1 = z2 the two teeth swap roles between A and E, so k(xi) = k(L - xi). This checks
    # the gear-2 conventions (S2M, tip at xi = 0) against gear 1's independently.
    p = GearParams(z1=40, z2=40, m2=17.29, J2=0.139)  # same bodies, hence the same bores
    g = Geometry.from_params(p)
    xi = _xi(g, 101)
    k = pe.pair_stiffness_raw(p, g, xi)
    np.testing.assert_allclose(k, k[::-1], rtol=1e-10)


def test_hertz_compliance_closed_form(table1):
    p, _ = table1
    # 4 (1 - 0.3^2) / (pi * 2.06e11 Pa * 0.2 m), worked by hand: 2.8123e-11 m/N.
    assert pe.hertz_compliance(p) == pytest.approx(2.8123e-11, rel=1e-4)
    p2 = p.replace(face_width=0.1, poisson=0.25, youngs_modulus=1e11)
    assert pe.hertz_compliance(p2) == pytest.approx(4 * 0.9375 / (math.pi * 1e11 * 0.1))


def test_pair_compliance_is_the_sum_of_the_parts(table1):
    p, g = table1
    xi = _xi(g, 21)
    parts = pe.hertz_compliance(p) + sum(
        sum(pe.tooth_compliances(p, g, xi, gear).values()) for gear in (1, 2)
    )
    np.testing.assert_allclose(pe.pair_stiffness_raw(p, g, xi), 1.0 / parts, rtol=1e-12)


def test_stiffness_scales_with_modulus_and_face_width(table1):
    p, g = table1
    xi = _xi(g, 11)
    k = pe.pair_stiffness_raw(p, g, xi)
    k2 = pe.pair_stiffness_raw(p.replace(face_width=0.4), g, xi)
    k3 = pe.pair_stiffness_raw(p.replace(youngs_modulus=1.03e11), g, xi)
    np.testing.assert_allclose(k2, 2 * k, rtol=1e-12)
    np.testing.assert_allclose(k3, 0.5 * k, rtol=1e-12)


def test_quadrature_is_converged(table1):
    p, g = table1
    xi = _xi(g)
    k = pe.pair_stiffness_raw(p, g, xi)
    k2 = pe.pair_stiffness_raw(p, g, xi, n_gauss=2 * pe.N_GAUSS)
    assert np.max(np.abs(k2 / k - 1)) < 1e-6


def _involute_tooth(rb: float, z: int, alpha0: float, r: float) -> tuple[float, float]:
    """Centre-line coordinate and half thickness of an involute tooth at radius r."""
    beta = math.pi / (2 * z) + (math.tan(alpha0) - alpha0)
    ar = math.acos(rb / r)
    half_angle = beta - (math.tan(ar) - ar)
    return r * math.cos(half_angle), r * math.sin(half_angle)


def _radial_compliances(p, rb, z, r_lo, r_c, a1):
    """Bending, shear, axial compliances of the involute between r_lo and r_c by quad."""
    E, nu, b = p.youngs_modulus, p.poisson, p.face_width
    G = E / (2 * (1 + nu))
    x_c, h_c = _involute_tooth(rb, z, p.pressure_angle, r_c)
    c, s = math.cos(a1), math.sin(a1)

    def integrand(r, which):
        x, h = _involute_tooth(rb, z, p.pressure_angle, r)
        eps = 1e-6 * (r_c - r_lo)
        r1, r2 = min(r + eps, r_c), max(r - eps, r_lo)
        dxdr = (_involute_tooth(rb, z, p.pressure_angle, r1)[0]
                - _involute_tooth(rb, z, p.pressure_angle, r2)[0]) / (r1 - r2)
        if which == "bending":
            f = (c * (x_c - x) - s * h_c) ** 2 / (E * 2 * h**3 * b / 3)
        elif which == "shear":
            f = 1.2 * c**2 / (G * 2 * h * b)
        else:
            f = s**2 / (E * 2 * h * b)
        return f * dxdr

    return {k: quad(integrand, r_lo, r_c, args=(k,), epsrel=1e-11, limit=200)[0]
            for k in ("bending", "shear", "axial")}


@pytest.mark.parametrize("gear", [1, 2])
def test_involute_integrals_match_an_independent_radial_integration(table1, gear):
    # Recompute bending, shear and axial compliances of the involute part by scipy.quad over
    # the radius, with the tooth shape from the polar involute equation instead of the
    # alpha parametrisation used by the module.
    p, g = table1
    z, rb, rf = (p.z1, g.rb1, g.rf1) if gear == 1 else (p.z2, g.rb2, g.rf2)
    xi = np.array([0.2, 0.5, 0.8]) * g.path_length
    got = pe.tooth_compliances(p, g, xi, gear, root_segment=False)
    a1 = pe.load_angle(p, g, xi, gear)
    s1m = g.s1a + xi
    sm = s1m if gear == 1 else g.s1s2 - s1m
    for j in range(xi.size):
        ref = _radial_compliances(p, rb, z, max(rb, rf), math.hypot(rb, sm[j]), a1[j])
        for key, value in ref.items():
            assert got[key][j] == pytest.approx(value, rel=1e-5), key


def test_root_segment_adds_compliance_to_gear_1_only(table1):
    p, g = table1
    assert g.rf1 < g.rb1 and g.rf2 > g.rb2  # the two cases of the Table 1 pair
    xi = _xi(g, 51)
    with_seg = pe.tooth_compliances(p, g, xi, 1)
    without = pe.tooth_compliances(p, g, xi, 1, root_segment=False)
    for key in ("bending", "shear", "axial"):
        assert np.all(with_seg[key] > without[key])
    np.testing.assert_array_equal(with_seg["fillet"], without["fillet"])
    assert np.all(pe.pair_stiffness_raw(p, g, xi, root_segment=False)
                  > pe.pair_stiffness_raw(p, g, xi))
    # The segment (1.5 mm of a 13.5 mm high tooth) is a correction, not the main term.
    total_with = sum(with_seg.values())
    total_without = sum(without.values())
    assert np.all(total_with < 1.5 * total_without)
    # Gear 2 has its root circle above the base circle: the switch must not matter.
    c2 = pe.tooth_compliances(p, g, xi, 2)
    c2n = pe.tooth_compliances(p, g, xi, 2, root_segment=False)
    for key in c2:
        np.testing.assert_array_equal(c2[key], c2n[key])


def test_root_segment_bending_matches_a_uniform_cantilever(table1):
    # The segment's extra bending compliance is that of a rectangular beam of half width
    # rb sin(alpha2) between the root and base circles: check it against a direct quad.
    p, g = table1
    xi = np.array([0.3 * g.path_length])
    alpha2 = math.pi / (2 * p.z1) + math.tan(p.pressure_angle) - p.pressure_angle
    hb = g.rb1 * math.sin(alpha2)
    x_lo, x_hi = math.sqrt(g.rf1**2 - hb**2), g.rb1 * math.cos(alpha2)
    a1 = float(pe.load_angle(p, g, xi, 1)[0])
    r_c = math.hypot(g.rb1, g.s1a + xi[0])
    x_c, h_c = _involute_tooth(g.rb1, p.z1, p.pressure_angle, r_c)
    inertia = 2 * hb**3 * p.face_width / 3
    extra = quad(lambda x: (math.cos(a1) * (x_c - x) - math.sin(a1) * h_c) ** 2
                 / (p.youngs_modulus * inertia), x_lo, x_hi)[0]
    with_seg = pe.tooth_compliances(p, g, xi, 1)["bending"][0]
    without = pe.tooth_compliances(p, g, xi, 1, root_segment=False)["bending"][0]
    assert with_seg - without == pytest.approx(extra, rel=1e-9)


def test_fillet_term_uses_sainsot_coefficients(table1):
    p, g = table1
    # Sainsot et al. (2004), Table 1, for h_fi = 1.2 and theta_f = 0.1 rad, evaluated by hand:
    # L* = 6.8045 + 0.0271*1.2 - 1.9986e-3*1.44 + 4.7702e-3*10 - 2.3015e-4*12 - 5.574e-5*100
    h, t = 1.2, 0.1
    basis = np.array([1 / t**2, h**2, h / t, 1 / t, h, 1.0])
    lstar = 6.8045 + 0.0271 * h - 1.9986e-3 * h**2 + 4.7702e-3 / t - 2.3015e-4 * h / t \
        - 5.574e-5 / t**2
    assert (pe.SAINSOT_COEFFS @ basis)[0] == pytest.approx(lstar, rel=1e-12)
    xi = _xi(g, 51)
    for gear in (1, 2):
        f = pe.tooth_compliances(p, g, xi, gear)["fillet"]
        assert np.all(f > 0) and np.all(np.isfinite(f))
    # The body term is of the same order as the tooth's own beam compliance at mid-path
    # (Sainsot's point: leaving it out overestimates the stiffness by tens of percent).
    for gear in (1, 2):
        c = pe.tooth_compliances(p, g, np.array([g.xi_pitch]), gear)
        beam = c["bending"][0] + c["shear"][0] + c["axial"][0]
        assert 0.3 < c["fillet"][0] / beam < 5


def test_default_bore_matches_table1_discs(table1):
    p, g = table1
    # Table 1's masses and inertias are those of steel (7850 kg/m^3) annular discs from the
    # bore to the pitch circle: the inferred bores must reproduce the masses.
    for gear, m, z in ((1, p.m1, p.z1), (2, p.m2, p.z2)):
        r_int = pe.bore_radius(p, g, gear)
        rp = p.module * z / 2
        mass = 7850 * math.pi * (rp**2 - r_int**2) * p.face_width
        assert mass == pytest.approx(m, rel=1e-2)
    # Inconsistent inertia (no real bore): falls back inside the allowed h_fi range.
    p_bad = p.replace(J1=1e-4)
    r = pe.bore_radius(p_bad, g, 1)
    assert g.rf1 / r == pytest.approx(pe.H_FI_RANGE[1])


def test_bad_gear_index(table1):
    p, g = table1
    with pytest.raises(ValueError, match="gear must be 1 or 2"):
        pe.tooth_compliances(p, g, np.array([0.0]), 3)
