"""The model's set-up as compiled code: gear data and effects in, the engine's `ModelData` out.

One compiled function, `setup` (entry point `setup_entry`, called from Python through
numba's dispatcher and from C at its address, as the step is), computes everything the
fast engine's records hold from the gear data and the effect choices: the geometry of the
path of contact, the mesh stiffness law (the potential-energy compliances of both teeth,
Eqs. of `gearpair.potential_energy`, on the spline's knots, the not-a-knot spline and its
mean; or the constant, rectangular or a resampled table law), the matrices' diagonals, the
damping coefficients (docs/model.md "Choices"), the highest natural frequency of the slip
model that bounds the step, the tolerances and the flags. The Python classes of the model
(`Geometry`, `MeshStiffness`, `potential_energy.tooth_compliances`) take their numbers from
the same compiled code, so there is one source of the set-up's arithmetic, and it gives the
same bits on every machine (`detmath`, `detlinalg`: no C library, BLAS or LAPACK).

What it reads and writes is a *set-up table* (int64 words, `table`): address and length of
each of `SETUP_ARRAYS`, in that order. The inputs are the gear data (`GearParams` fields in
their declared order, `GP`), the choices (`C_*`) and, for a table law only, the law resampled
on its uniform grid; the outputs are the geometry (`GEO_*`) and the arrays of `ModelData`
(the stiffness arrays at their capacity: `flag[I_NTAB]` says how much is used); one float
scratch buffer of `N_SCRATCH` words holds the rest (no allocation: numba's runtime is off).
The set-up returns a status (`SETUP_*`): the checks that need the geometry (interference,
contact ratio) are made here, so every front door refuses the same gear data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from ..jitcache import jit, jit_entry
from ..params import H_FI_RANGE, N_GAUSS, N_SPLINE, N_TABLE, SAINSOT_COEFFS, GearParams
from . import detmath as dm
from .detlinalg import OK, cubic_spline_into, eigh_generalized_into, matvec_into
from .layout import (
    I_BACK,
    I_FRIC,
    I_IX,
    I_KIND,
    I_LTI,
    I_MAXEV,
    I_METHOD,
    I_NIX,
    I_NP,
    I_NSAMP,
    I_NTAB,
    I_SEP,
    I_SLIDE,
    I_TIE,
    I_TORS,
    I_VARY,
    KIND_CONSTANT,
    KIND_CUBIC,
    KIND_TABLE,
    N_MI,
    N_MP,
    N_Y,
    P_BACK,
    P_C,
    P_CM,
    P_DB0,
    P_DB1,
    P_DX,
    P_INVDX,
    P_IPER,
    P_IRB1,
    P_IRB2,
    P_KB,
    P_KMEAN,
    P_L,
    P_MAXSTEP,
    P_MINV,
    P_MU,
    P_MUS,
    P_PB,
    P_PER,
    P_RATIO,
    P_RB1,
    P_RB2,
    P_RTOL,
    P_S1A,
    P_S1S2,
    P_SPACING,
    P_TTOL,
    P_VEPS,
    P_VS,
    P_XIP,
    Y_A,
    ModelData,
)
from .tableaux import METHOD_CODE
from .views import array_at, dims, word

# -- inputs -----------------------------------------------------------------------------------
#: The gear data vector: `GearParams` fields in their declared order (the FMU's order too).
GP_NAMES = tuple(f.name for f in fields(GearParams))
GP = {name: i for i, name in enumerate(GP_NAMES)}
N_GP = len(GP_NAMES)
(GP_M1, GP_M2, GP_J1, GP_J2, GP_Z1, GP_Z2, GP_MODULE, GP_WIDTH, GP_ALPHA, GP_HA, GP_HF,
 GP_KB1, GP_KB2, GP_KR2, GP_KR1, GP_ZETA, GP_MU, GP_KM, GP_E, GP_NU) = (
    GP[n] for n in ("m1", "m2", "J1", "J2", "z1", "z2", "module", "face_width",
                    "pressure_angle", "addendum_coef", "dedendum_coef", "kb1", "kb2", "kr2",
                    "kr1", "damping_ratio", "mu", "km_mean", "youngs_modulus", "poisson"))

#: The choices (float words; NaN: not given). C_LAW: `LAW_*`; C_BACK: backlash (m, NaN: no
#: back flank); C_MUS: the static coefficient (mu when not given); C_TABMEAN: the mean of a
#: table law (N/m, computed with its resampling in Python); the rest as `FastOptions`.
(C_LAW, C_SCALE, C_SEP, C_FRIC, C_VEPS, C_SLIDE, C_TIE, C_BACK, C_TORS, C_MUS, C_VS, C_RTOL,
 C_ATOL, C_MAXSTEP, C_NSAMP, C_SPACING, C_TTOL, C_MAXEV, C_LTI, C_METHOD, C_TABMEAN) = range(21)
N_C = 21
LAW_CONSTANT, LAW_RECTANGULAR, LAW_POTENTIAL, LAW_TABLE = range(4)
LAW_CODE = {"constant": LAW_CONSTANT, "rectangular": LAW_RECTANGULAR,
            "potential_energy": LAW_POTENTIAL, "table": LAW_TABLE}

# -- outputs ----------------------------------------------------------------------------------
#: The geometry (m; `gearpair.geometry.Geometry`'s fields in order, n_pairs as a float).
GEO_NAMES = ("rb1", "rb2", "ra1", "ra2", "rf1", "rf2", "center_distance", "s1s2",
             "base_pitch", "s1a", "s1b", "s1p", "s1d", "s1e", "contact_ratio", "n_pairs")
(GEO_RB1, GEO_RB2, GEO_RA1, GEO_RA2, GEO_RF1, GEO_RF2, GEO_A, GEO_S1S2, GEO_PB, GEO_S1A,
 GEO_S1B, GEO_S1P, GEO_S1D, GEO_S1E, GEO_EPS, GEO_NP) = range(16)
N_GEO = 16

CAP_X, CAP_K, CAP_S = N_TABLE, max(N_TABLE, 4 * (N_SPLINE - 1)), N_TABLE - 1

# scratch offsets (float words): Gauss nodes and weights, the raw stiffness on the knots,
# the spline's work rows, the eigenproblem (K, M, V 6 x 6, its work 15 x 6, eigenvalues)
SC_GT, SC_GW, SC_KRAW, SC_SPW = 0, 32, 64, 105
SC_K, SC_M, SC_V, SC_EW, SC_LAM = 269, 305, 341, 377, 467
N_SCRATCH = 473

#: The set-up table's arrays in order, with their kind and length (None: the caller's).
SETUP_ARRAYS = (("gp", "f", N_GP), ("choice", "f", N_C), ("tab_x", "f", None),
                ("tab_k", "f", None), ("geo", "f", N_GEO), ("par", "f", N_MP),
                ("flag", "i", N_MI), ("atol", "f", N_Y), ("xi_knots", "f", CAP_X),
                ("k_coef", "f", CAP_K), ("k_slope", "f", CAP_S), ("scratch", "f", N_SCRATCH))
N_SETUP_TABLE = 2 * len(SETUP_ARRAYS)

#: Status of the set-up: what `setup_message` says of each.
(SETUP_OK, SETUP_INTERFERENCE, SETUP_CONTACT_RATIO, SETUP_SPLINE, SETUP_MODES, SETUP_GRID,
 SETUP_TABLE) = range(7)

H_FI_LO, H_FI_HI = H_FI_RANGE  # the range of rf / r_int
# typical magnitudes of y for the default absolute tolerance (`FastEngine`)
SCALE = np.array([1e-5] * 6 + [1e-3] * 6 + [1.0] * 4 + [1e-5, 1e-3])


# -- elementary functions: one copy each in the set-up's code ------------------------------------
# `detmath`'s are always inlined (the engine calls them at few sites); the set-up calls them
# at some fifteen, where inlined copies cost compile time and save nothing measurable
@jit
def sin_(x):
    return dm.sin(x)


@jit
def cos_(x):
    return dm.cos(x)


@jit
def tan_(x):
    return dm.tan(x)


@jit
def asin_(x):
    return dm.asin(x)


@jit
def acos_(x):
    return dm.acos(x)


# -- geometry ---------------------------------------------------------------------------------
@jit
def base_radius(gp, z):
    """Base radius (m) of a gear of ``z`` teeth, module z cos(alpha) / 2."""
    return gp[GP_MODULE] * z * cos_(gp[GP_ALPHA]) / 2.0


@jit
def geometry_into(gp, geo):
    """The geometry of the path of contact (`GEO_*`, docs/model.md Fig. 3) into ``geo``;
    returns SETUP_OK, SETUP_INTERFERENCE or SETUP_CONTACT_RATIO."""
    m, a0, z1, z2 = gp[GP_MODULE], gp[GP_ALPHA], gp[GP_Z1], gp[GP_Z2]
    rb1, rb2 = base_radius(gp, z1), base_radius(gp, z2)
    ra1 = m * z1 / 2 + gp[GP_HA] * m
    ra2 = m * z2 / 2 + gp[GP_HA] * m
    a = m * (z1 + z2) / 2
    s1s2 = a * sin_(a0)
    pb = math.pi * m * cos_(a0)
    s1a = s1s2 - math.sqrt(ra2 * ra2 - rb2 * rb2)
    s1e = math.sqrt(ra1 * ra1 - rb1 * rb1)
    vals = (rb1, rb2, ra1, ra2, m * z1 / 2 - gp[GP_HF] * m, m * z2 / 2 - gp[GP_HF] * m, a,
            s1s2, pb, s1a, s1e - pb, rb1 * tan_(a0), s1a + pb, s1e)
    for i in range(14):
        geo[i] = vals[i]
    if s1a < 0 or s1e > s1s2:
        return SETUP_INTERFERENCE
    eps = (s1e - s1a) / pb
    geo[GEO_EPS] = eps
    geo[GEO_NP] = math.ceil(eps)
    return SETUP_CONTACT_RATIO if eps < 1.0 else SETUP_OK


# -- potential-energy stiffness ---------------------------------------------------------------
@jit
def gauss_legendre_into(t, w):
    """Nodes (ascending) and weights of the Gauss-Legendre rule of ``t.size`` points on
    [-1, 1]: Newton on the three-term recurrence from cos(pi (i + 3/4) / (n + 1/2)), to
    convergence and one step more (not LAPACK's eigenvalues, whose bits vary by kernel)."""
    n = t.shape[0]
    for i in range(n):
        x = cos_(np.pi * (i + 0.75) / (n + 0.5))
        for _ in range(100):
            p1, dp = legendre(x, n)
            dx = p1 / dp
            x -= dx
            if abs(dx) <= 1e-16 * abs(x) or abs(dx) < 1e-300:
                break
        p1, dp = legendre(x, n)
        t[n - 1 - i] = x
        w[n - 1 - i] = 2.0 / ((1.0 - x * x) * dp * dp)


@jit
def legendre(x, n):
    """(P_n(x), P_n'(x)) by the three-term recurrence."""
    p0, p1 = 1.0, x
    for k in range(2, n + 1):
        p0, p1 = p1, ((2 * k - 1) * x * p1 - (k - 1) * p0) / k
    return p1, n * (x * p1 - p0) / (x * x - 1.0)


@jit
def inv(a):
    """Involute function tan(a) - a."""
    return tan_(a) - a


@jit
def tooth_data(gp, geo, gear):
    """(z, rb, rf, pitch radius, m, J) of gear 1 or 2."""
    if gear == 1:
        return (gp[GP_Z1], geo[GEO_RB1], geo[GEO_RF1], gp[GP_MODULE] * gp[GP_Z1] / 2.0,
                gp[GP_M1], gp[GP_J1])
    return (gp[GP_Z2], geo[GEO_RB2], geo[GEO_RF2], gp[GP_MODULE] * gp[GP_Z2] / 2.0,
            gp[GP_M2], gp[GP_J2])


@jit
def bore_radius(gp, geo, gear):
    """Bore radius (m) of the fillet-foundation term: r_int^2 = 2 J / m - r_p^2, clipped to
    rf / r_int in [1.1, 3.3] (`gearpair.potential_energy.bore_radius`)."""
    _, _, rf, rp, m, J = tooth_data(gp, geo, gear)
    r2 = 2.0 * J / m - rp * rp
    lo, hi = rf / H_FI_HI, rf / H_FI_LO
    r = math.sqrt(r2) if r2 > 0.0 else lo
    return min(max(r, lo), hi)


@jit
def tooth_root(rb, rf, alpha2):
    """(alpha at the root end of the involute, theta_f, x_root, h_b): below the base circle
    the straight part of half width h_b; above it only the involute above the root."""
    if rf < rb:
        h_b = rb * sin_(alpha2)
        return alpha2, asin_(min(h_b / rf, 1.0)), math.sqrt(max(rf * rf - h_b * h_b, 0.0)), \
            h_b
    c = acos_(rb / rf)
    theta_f = alpha2 - inv(c)
    return alpha2 - tan_(c), theta_f, rf * cos_(theta_f), 0.0


@jit
def involute_part(gp, rb, alpha2, a1, alpha_root, gauss):
    """Bending, shear and axial compliance sums (before the load-angle factors) of the
    involute part, Gauss-Legendre over alpha in [-alpha1, alpha_root], summed in order."""
    t, w = gauss
    E, b = gp[GP_E], gp[GP_WIDTH]
    c1, s1 = cos_(a1), sin_(a1)
    phi_c = a1 + alpha2
    x_c = rb * (c1 + phi_c * s1)
    h_c = rb * (phi_c * c1 - s1)
    lo = -a1
    half = 0.5 * max(alpha_root - lo, 0.0)
    shear_mod = E / (2.0 * (1.0 + gp[GP_NU]))
    bend = 0.0
    shear = 0.0
    axial = 0.0
    for k in range(t.shape[0]):
        al = lo + half * (t[k] + 1.0)
        roll = alpha2 - al
        ca, sa = cos_(al), sin_(al)
        x = rb * (ca - roll * sa)
        h = rb * (sa + roll * ca)
        dx = rb * roll * ca * half
        moment = c1 * (x_c - x) - s1 * h_c
        inertia = 2.0 * (h * h * h) * b / 3.0
        area = 2.0 * h * b
        bend += w[k] * (moment * moment) / (E * inertia) * dx
        shear += w[k] * 1.2 / (shear_mod * area) * dx
        axial += w[k] / (E * area) * dx
    return bend, shear * (c1 * c1), axial * (s1 * s1), x_c, h_c


@jit
def tooth_compliance(gp, geo, xi, gear, opts, out):
    """Bending, shear, axial and fillet-foundation compliances (m/N) of one tooth of gear
    ``gear`` loaded at ``xi`` (m from A) into out[0:4] (`potential_energy.tooth_compliances`).
    ``opts``: (root segment, bore radius or NaN for `bore_radius`, (Gauss nodes, weights))."""
    root_segment, r_int, gauss = opts
    z, rb, rf, _, _, _ = tooth_data(gp, geo, gear)
    E, b = gp[GP_E], gp[GP_WIDTH]
    alpha2 = math.pi / (2.0 * z) + inv(gp[GP_ALPHA])
    s1m = geo[GEO_S1A] + xi
    a1 = (s1m if gear == 1 else geo[GEO_S1S2] - s1m) / rb - alpha2  # the load angle
    c1, s1 = cos_(a1), sin_(a1)
    alpha_root, theta_f, x_root, h_b = tooth_root(rb, rf, alpha2)
    bend, shear, axial, x_c, h_c = involute_part(gp, rb, alpha2, a1, alpha_root, gauss)
    if rf < rb and root_segment:  # the straight part below the base circle, in closed form
        x_base = rb * cos_(alpha2)
        d = x_base - x_root
        inertia_b = 2.0 * (h_b * h_b * h_b) * b / 3.0
        area_b = 2.0 * h_b * b
        m_root = c1 * (x_c - x_root) - s1 * h_c
        m_base = c1 * (x_c - x_base) - s1 * h_c
        bend = bend + (m_root * m_root * m_root - m_base * m_base * m_base) \
            / (3.0 * c1) / (E * inertia_b)
        shear = shear + 1.2 * (c1 * c1) * d / (E / (2.0 * (1.0 + gp[GP_NU])) * area_b)
        axial = axial + (s1 * s1) * d / (E * area_b)
    out[0], out[1], out[2] = bend, shear, axial
    out[3] = fillet(gp, (rf, rb, c1, a1, x_root, theta_f),
                    bore_radius(gp, geo, gear) if math.isnan(r_int) else r_int, out[4:])


@jit
def fillet(gp, tooth, r_in, work):
    """Fillet-foundation compliance (m/N) of Sainsot, Velex & Duverger (2004); ``tooth``:
    (rf, rb, cos alpha1, alpha1, x_root, theta_f); ``work``: 10 floats."""
    rf, rb, c1, a1, x_root, theta_f = tooth
    h_fi = rf / r_in
    basis, coef = work[:6], work[6:10]
    basis[0] = 1.0 / (theta_f * theta_f)
    basis[1] = h_fi * h_fi
    basis[2] = h_fi / theta_f
    basis[3] = 1.0 / theta_f
    basis[4] = h_fi
    basis[5] = 1.0
    matvec_into(SAINSOT_COEFFS, basis, coef)
    u = (rb / c1 - x_root) / (2.0 * rf * theta_f)
    ta = tan_(a1)
    return (c1 * c1) / (gp[GP_E] * gp[GP_WIDTH]) \
        * (coef[0] * (u * u) + coef[1] * u + coef[2] * (1.0 + coef[3] * (ta * ta)))


@jit
def hertz_compliance(gp):
    """Hertzian contact compliance 4 (1 - nu^2) / (pi E b) (m/N)."""
    nu = gp[GP_NU]
    return 4.0 * (1.0 - nu * nu) / (math.pi * gp[GP_E] * gp[GP_WIDTH])


@jit
def pair_stiffness_into(gp, geo, xi, gauss, out, work):
    """Stiffness (N/m) of one tooth pair at each ``xi``, not scaled: 1 / (Hertz + both
    teeth's bending, shear, axial and fillet compliances); ``work``: 14 floats."""
    for i in range(xi.shape[0]):
        total = hertz_compliance(gp)
        for gear in (1, 2):
            tooth_compliance(gp, geo, xi[i], gear, (True, math.nan, gauss), work)
            total = total + work[0] + work[1] + work[2] + work[3]
        out[i] = 1.0 / total


# -- stiffness law ----------------------------------------------------------------------------
@jit
def linspace_into(stop, out):
    """out[i] = i (stop / (n - 1)), the last exactly ``stop``, as numpy's linspace from 0."""
    n = out.shape[0]
    step = stop / (n - 1)
    for i in range(n):
        out[i] = i * step + 0.0
    out[n - 1] = stop


@jit
def spline_law(gp, geo, scale_to_mean, tabs, sc):
    """The potential-energy law as a not-a-knot spline on N_SPLINE knots into ``tabs`` =
    (knots, coefficients as (N_SPLINE - 1, 4), slopes), scaled to km_mean when asked;
    returns (status, time mean of the total (N/m))."""
    xi, cubic, slope = tabs
    n = xi.shape[0]
    linspace_into(geo[GEO_S1E] - geo[GEO_S1A], xi)
    t = sc[SC_GT:SC_GT + N_GAUSS]
    w = sc[SC_GW:SC_GW + N_GAUSS]
    gauss_legendre_into(t, w)
    kraw = sc[SC_KRAW:SC_KRAW + n]
    pair_stiffness_into(gp, geo, xi, (t, w), kraw, sc[SC_K:SC_K + 14])
    spw = array_at(word(sc, SC_SPW), dims(4, n), 0.0)
    if cubic_spline_into(xi, kraw, cubic, spw) != OK:
        return SETUP_SPLINE, 0.0
    h = xi[1] - xi[0]
    total = 0.0  # (1/pb) integral_0^L k dxi, exact for the spline, summed in order
    for i in range(n - 1):
        c0, c1, c2, c3 = cubic[i, 0], cubic[i, 1], cubic[i, 2], cubic[i, 3]
        total += ((c3 * (h / 4.0) + c2 / 3.0) * h + c1 / 2.0) * h * h + c0 * h
    mean = total / geo[GEO_PB]
    if scale_to_mean:
        f = gp[GP_KM] / mean
        for i in range(n - 1):
            for j in range(4):
                cubic[i, j] *= f
        mean = gp[GP_KM]
    for i in range(n - 1):
        slope[i] = cubic[i, 1]
    return SETUP_OK, mean


@jit
def flat_law(k0, L, tabs):
    """A law constant along the path (constant or rectangular): two points, slope 0."""
    xi, k, slope = tabs
    xi[0], xi[1] = 0.0, L
    k[0], k[1] = k0, k0
    slope[0] = (k0 - k0) / (L - 0.0)


@jit
def table_law(tab, tabs):
    """A table law (resampled in Python): its points and slopes; SETUP_TABLE if it is not
    N_TABLE points."""
    tab_x, tab_k = tab
    xi, k, slope = tabs
    if tab_x.shape[0] != N_TABLE or tab_k.shape[0] != N_TABLE:
        return SETUP_TABLE
    for i in range(N_TABLE):
        xi[i] = tab_x[i]
        k[i] = tab_k[i]
    for i in range(N_TABLE - 1):
        slope[i] = (k[i + 1] - k[i]) / (xi[i + 1] - xi[i])
    return SETUP_OK


@jit
def stiffness_law(gp, ch, geo, tab, out, sc):
    """The stiffness law of choice C_LAW into the tables of ``out`` (`SETUP_ARRAYS`' outputs);
    returns (status, number of knots, time mean of the total (N/m))."""
    _, par, flag, _, xi, kc, ks = out
    law = int(ch[C_LAW])
    L = geo[GEO_S1E] - geo[GEO_S1A]
    if law == LAW_POTENTIAL:
        cubic = array_at(word(kc, 0), dims(N_SPLINE - 1, 4), 0.0)
        st, mean = spline_law(gp, geo, ch[C_SCALE] != 0.0,
                              (xi[:N_SPLINE], cubic, ks[:N_SPLINE - 1]), sc)
        flag[I_KIND] = KIND_CUBIC
        return st, N_SPLINE, mean
    if law == LAW_TABLE:
        flag[I_KIND] = KIND_TABLE
        return table_law(tab, (xi, kc, ks)), N_TABLE, ch[C_TABMEAN]
    flag[I_KIND] = KIND_CONSTANT if law == LAW_CONSTANT else KIND_TABLE
    k0 = gp[GP_KM] if law == LAW_CONSTANT else gp[GP_KM] / geo[GEO_EPS]
    flat_law(k0, L, (xi, kc, ks))
    return SETUP_OK, 2, gp[GP_KM]


# -- the modes' step bound --------------------------------------------------------------------
@jit
def top_frequency(gp, geo, km, torsional, sc):
    """The highest natural frequency (Hz) of the slip model, Eqs. (4)-(7) with Theta = 1 and
    the mean mesh stiffness ``km`` (`gearpair.modal.natural_frequencies`), or -1.0 when the
    eigen-solver fails."""
    mdiag, kdiag = masses(gp, geo), (gp[GP_KB1], gp[GP_KB1], gp[GP_KR1], gp[GP_KB2],
                                     gp[GP_KB2], gp[GP_KR2])
    g = (0.0, 1.0, 1.0, 0.0, -1.0, 1.0)  # delta = G . q, Eq. (3)
    n = 2 if torsional else 6
    K = array_at(word(sc, SC_K), dims(n, n), 0.0)
    M = array_at(word(sc, SC_M), dims(n, n), 0.0)
    for a in range(n):
        i = 2 + 3 * a if torsional else a  # the torsional model keeps u1, u2
        for b in range(n):
            j = 2 + 3 * b if torsional else b
            K[a, b] = (kdiag[i] if i == j else 0.0) + km * (g[i] * g[j])
            M[a, b] = mdiag[i] if i == j else 0.0
    lam = sc[SC_LAM:SC_LAM + n]
    work = array_at(word(sc, SC_EW), dims(2 * n + 3, n), 0.0)
    V = array_at(word(sc, SC_V), dims(n, n), 0.0)
    if eigh_generalized_into(K, M, lam, V, work) != OK:
        return -1.0
    return math.sqrt(max(lam[n - 1], 0.0)) / (2 * np.pi)


@jit
def masses(gp, geo):
    """Diagonal of M (kg), Eq. (5): m1, m1, J1/rb1^2, m2, m2, J2/rb2^2."""
    rb1, rb2 = geo[GEO_RB1], geo[GEO_RB2]
    return (gp[GP_M1], gp[GP_M1], gp[GP_J1] / (rb1 * rb1), gp[GP_M2], gp[GP_M2],
            gp[GP_J2] / (rb2 * rb2))


@jit
def damping(zeta, k, m):
    """2 zeta sqrt(k m) (N.s/m): the damping of every spring (docs/model.md "Choices")."""
    return 2.0 * zeta * math.sqrt(k * m)


# -- the records ------------------------------------------------------------------------------
@jit
def model_constants(gp, ch, geo, mean, par):
    """`ModelData.par` (`engine.model_constants`) before the step bound and table spacing."""
    md = masses(gp, geo)
    z = gp[GP_ZETA]
    m_equiv = md[2] * md[5] / (md[2] + md[5])
    cdiag = (damping(z, gp[GP_KB1], gp[GP_M1]), damping(z, gp[GP_KB1], gp[GP_M1]),
             damping(z, gp[GP_KR1], md[2]), damping(z, gp[GP_KB2], gp[GP_M2]),
             damping(z, gp[GP_KB2], gp[GP_M2]), damping(z, gp[GP_KR2], md[5]))
    kdiag = (gp[GP_KB1], gp[GP_KB1], gp[GP_KR1], gp[GP_KB2], gp[GP_KB2], gp[GP_KR2])
    for i in range(6):
        par[P_MINV + i] = 1.0 / md[i]
        par[P_C + i] = cdiag[i]
        par[P_KB + i] = kdiag[i]
    rb1, rb2, L, per = geo[GEO_RB1], geo[GEO_RB2], geo[GEO_S1E] - geo[GEO_S1A], \
        geo[GEO_NP] * geo[GEO_PB]
    par[P_RB1], par[P_RB2], par[P_RATIO] = rb1, rb2, gp[GP_Z1] / gp[GP_Z2]
    par[P_CM], par[P_MU] = damping(z, gp[GP_KM], m_equiv), gp[GP_MU]
    par[P_VEPS], par[P_S1A], par[P_S1S2], par[P_PB] = ch[C_VEPS], geo[GEO_S1A], \
        geo[GEO_S1S2], geo[GEO_PB]
    par[P_L], par[P_PER], par[P_XIP] = L, per, geo[GEO_S1P] - geo[GEO_S1A]
    par[P_KMEAN], par[P_IRB1], par[P_IRB2], par[P_IPER] = mean, 1.0 / rb1, 1.0 / rb2, 1.0 / per
    par[P_RTOL], par[P_TTOL] = ch[C_RTOL], ch[C_TTOL]
    par[P_BACK] = 0.0 if math.isnan(ch[C_BACK]) else ch[C_BACK]
    par[P_MUS], par[P_VS] = ch[C_MUS], ch[C_VS]
    # the physical bound of the DTE (`gearpair.equations.Model.dte_bound`)
    par[P_DB0], par[P_DB1] = 0.1 * gp[GP_MODULE], 20.0 / (rb1 * mean)


@jit
def model_flags(ch, geo, flag):
    """`ModelData.flag` (`engine.model_flags`) after the stiffness kind: the effects, the
    options and the integrated components (`engine.integrated_components`)."""
    law, fric, tors = int(ch[C_LAW]), int(ch[C_FRIC]), ch[C_TORS] != 0.0
    flat = law == LAW_CONSTANT or law == LAW_RECTANGULAR
    flag[I_NP] = int(geo[GEO_NP])
    flag[I_VARY] = 0 if flat else 1
    flag[I_SEP], flag[I_FRIC] = int(ch[C_SEP]), fric
    flag[I_SLIDE], flag[I_TIE] = int(ch[C_SLIDE]), int(ch[C_TIE])
    flag[I_NSAMP], flag[I_MAXEV] = int(ch[C_NSAMP]), int(ch[C_MAXEV])
    flag[I_BACK] = 0 if math.isnan(ch[C_BACK]) else 1
    flag[I_TORS] = 1 if tors else 0
    # constant coefficients between switches: the exact propagator replaces Runge-Kutta
    flag[I_LTI] = 1 if (fric == 0 and flat and ch[C_LTI] != 0.0) else 0
    flag[I_METHOD] = int(ch[C_METHOD])
    n = 0
    for c in range(N_Y):
        rate = c >= 6 and c < 12
        q = c - 6 if rate else c
        keep = c == Y_A or c == 12 or c == 13 or (c < 12 and (q == 2 or q == 5))
        if c < 12 and (q == 1 or q == 4):
            keep = not tors  # y1, y2 along the line of action
        if c < 12 and (q == 0 or q == 3):
            keep = not tors and fric != 0  # x1, x2: driven only by the friction forces
        if c == 14:
            keep = fric != 0
        if c == 15:
            keep = not flat
        if keep:
            flag[I_IX + n] = c
            n += 1
    flag[I_NIX] = n


@jit
def step_bounds(gp, ch, geo, out, sc):
    """The step bound, the sample spacing and the absolute tolerances; False when the
    eigen-solver failed."""
    _, par, flag, atol, _, _, _ = out
    max_step = ch[C_MAXSTEP]
    if math.isnan(max_step):  # half the period of the highest slip mode
        top = top_frequency(gp, geo, par[P_KMEAN], flag[I_TORS] != 0, sc)
        if not top > 0.0:
            return False
        max_step = 0.5 / top
    par[P_MAXSTEP] = max_step
    spacing = ch[C_SPACING]
    par[P_SPACING] = max_step / (int(ch[C_NSAMP]) + 1) if math.isnan(spacing) else spacing
    for i in range(N_Y):
        atol[i] = SCALE[i] * ch[C_RTOL] if math.isnan(ch[C_ATOL]) else ch[C_ATOL]
    return True


@jit
def table_spacing(par, flag, xi, ntab):
    """The stiffness table's spacing into ``par``; False unless its knots are uniform from
    0 to the path length."""
    flag[I_NTAB] = ntab
    par[P_DX] = par[P_L] / (ntab - 1)
    par[P_INVDX] = 1.0 / par[P_DX]
    for i in range(ntab):
        if abs(xi[i] - par[P_DX] * i) > 1e-9 * par[P_DX]:
            return False
    return True


@jit
def setup(inp, out, sc):
    """The model's records from the gear data and choices (module docstring): ``inp`` =
    (gp, choices, (tab_x, tab_k)), ``out`` = (geo, par, flag, atol, xi, kc, ks); returns a
    `SETUP_*` status."""
    gp, ch, tab = inp
    geo, par, flag = out[0], out[1], out[2]
    for i in range(par.shape[0]):
        par[i] = 0.0
    for i in range(flag.shape[0]):
        flag[i] = 0
    st = geometry_into(gp, geo)
    if st != SETUP_OK:
        return st
    st, ntab, mean = stiffness_law(gp, ch, geo, tab, out, sc)
    if st != SETUP_OK:
        return st
    model_constants(gp, ch, geo, mean, par)
    model_flags(ch, geo, flag)
    if not step_bounds(gp, ch, geo, out, sc):
        return SETUP_MODES
    if not table_spacing(par, flag, out[4], ntab):
        return SETUP_GRID
    return SETUP_OK


@jit
def setup_table(tab):
    """(inputs, outputs, scratch) of `setup` from a set-up table (`SETUP_ARRAYS`' order:
    address and length of each)."""
    def f(k):
        return array_at(tab[2 * k], (tab[2 * k + 1],), 0.0)

    def i(k):
        return array_at(tab[2 * k], (tab[2 * k + 1],), 0)

    return (f(0), f(1), (f(2), f(3))), (f(4), f(5), i(6), f(7), f(8), f(9), f(10)), f(11)


@jit_entry
def setup_entry(table_address):
    """`setup` of the set-up table at ``table_address`` (int64 words, `SETUP_ARRAYS`)."""
    inp, out, sc = setup_table(array_at(table_address, (np.int64(N_SETUP_TABLE),), 0))
    return setup(inp, out, sc)


@jit_entry
def compliances_entry(gp, xi, gear, opts, geo, out):
    """`tooth_compliance` of gear ``gear`` at each ``xi`` into the rows of ``out`` (bending,
    shear, axial, fillet and 10 work columns), the geometry into ``geo``; ``opts``: (root
    segment, bore radius or NaN, and two buffers the Gauss nodes and weights go into, as
    many as the rule has points). Returns the geometry's status."""
    root_segment, r_int, t, w = opts
    st = geometry_into(gp, geo)
    if st != SETUP_INTERFERENCE and xi.shape[0] > 0:
        gauss_legendre_into(t, w)
        for i in range(xi.shape[0]):
            tooth_compliance(gp, geo, xi[i], gear, (root_segment, r_int, (t, w)), out[i])
    return st



# -- Python -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class FastOptions:
    """Integrator options of `FastEngine` (keywords of its constructor).

    Attributes
    ----------
    atol : absolute tolerance (all states); default ``rtol`` times typical magnitudes
        (1e-5 m, 1e-3 m/s, 1 J), as the reference
    max_step : largest step (s); default half the period of the highest slip-model mode
    n_samples, sample_spacing : every accepted step is scanned for sign changes at
        dense-output samples at most ``sample_spacing`` apart (default
        ``max_step / (n_samples + 1)``: the spacing of the reference's 8 interior samples on
        its longest step); short steps are checked at their end only
    t_tol : time tolerance (s) of the event refinement (plus 8 ulp of t)
    max_events : bound on switches per `advance` call; more raises RuntimeError (a stall)
    exact_lti : with friction off and constant or rectangular stiffness the equations have
        constant coefficients between switches; integrate them with the exact propagator
        ``expm(A h)`` (`lti.piece_lti`) instead of Runge-Kutta. False keeps Runge-Kutta
        (for comparison).
    method : ``"dop853"`` (default) or ``"dp5"``, the Runge-Kutta pair (`tableaux`);
        ``gearpair bench`` compares the two
    """

    atol: float | None = None
    max_step: float | None = None
    n_samples: int = 8
    sample_spacing: float | None = None
    t_tol: float = 1e-14
    max_events: int = 100_000
    exact_lti: bool = True
    method: str = "dop853"

    def __post_init__(self) -> None:
        if self.method not in METHOD_CODE:
            raise ValueError(f"method = {self.method!r} is not known; allowed "
                             f"{', '.join(sorted(METHOD_CODE))}")
        if not (1 <= int(self.n_samples) <= 1000):
            raise ValueError(f"n_samples = {self.n_samples!r} is out of range; allowed "
                             "[1, 1000]")


class Setup(NamedTuple):
    """What `run_setup` gives: the geometry (`GEO_*`) and the engine's model data."""

    geo: np.ndarray
    md: ModelData


def gear_vector(p: GearParams) -> np.ndarray:
    """The gear data as `setup` reads them (`GP`)."""
    return np.array([float(getattr(p, n)) for n in GP_NAMES])


def choice_vector(p: GearParams, effects=None, *, stiffness=None, rtol: float = 1e-8,
                  options=None, table_mean: float = math.nan) -> np.ndarray:
    """The choices (`C_*`) of ``effects`` (default `Effects()`; ``stiffness`` replaces its
    law) and of the integrator ``options`` (a `FastOptions`; default its defaults)."""
    from ..effects import Effects
    from .layout import FRICTION_CODE

    fx = Effects() if effects is None else effects
    spec = fx.stiffness if stiffness is None else stiffness
    ch = np.full(N_C, math.nan)
    ch[C_LAW], ch[C_SCALE] = LAW_CODE[spec.kind], float(spec.scale_to_mean)
    ch[C_SEP], ch[C_FRIC], ch[C_VEPS] = float(fx.separation), FRICTION_CODE[fx.friction], \
        fx.v_eps
    ch[C_SLIDE], ch[C_TIE] = float(fx.sliding == "full"), float(fx.stick_tie == "paper")
    ch[C_BACK] = math.nan if fx.backlash is None else float(fx.backlash)
    ch[C_TORS] = float(fx.dof == "torsional")
    ch[C_MUS] = float(p.mu if fx.mu_static is None else fx.mu_static)
    ch[C_VS] = float(fx.stribeck_velocity or 0.0)
    ch[C_RTOL], ch[C_TABMEAN] = float(rtol), float(table_mean)
    op = FastOptions() if options is None else options
    for c, v in ((C_ATOL, op.atol), (C_MAXSTEP, op.max_step),
                 (C_SPACING, op.sample_spacing)):
        ch[c] = math.nan if v is None else float(v)
    ch[C_NSAMP], ch[C_TTOL] = int(op.n_samples), float(op.t_tol)
    ch[C_MAXEV], ch[C_LTI] = int(op.max_events), float(bool(op.exact_lti))
    ch[C_METHOD] = METHOD_CODE[op.method]
    return ch


def run_setup(p: GearParams, effects=None, *, stiffness=None, rtol: float = 1e-8,
              options=None, table=None) -> Setup:
    """The compiled `setup` of gear data ``p`` with ``effects`` (see `choice_vector`);
    ``table``: (knots, values, mean) of a table law resampled on `N_TABLE` points. Raises
    ValueError (gear data that cannot mesh) or numpy.linalg.LinAlgError as `setup_message`
    says."""
    tab_x, tab_k, mean = (np.zeros(2), np.zeros(2), math.nan) if table is None else table
    arrays = [gear_vector(p), choice_vector(p, effects, stiffness=stiffness, rtol=rtol,
                                            options=options, table_mean=mean),
              np.ascontiguousarray(tab_x, dtype=float), np.ascontiguousarray(tab_k, dtype=float)]
    for _, kind, n in SETUP_ARRAYS[4:]:
        arrays.append(np.zeros(n, dtype=np.float64 if kind == "f" else np.int64))
    words = np.zeros(N_SETUP_TABLE, dtype=np.int64)
    for k, a in enumerate(arrays):
        words[2 * k], words[2 * k + 1] = a.ctypes.data, a.shape[0]
    status = int(setup_entry(np.int64(words.ctypes.data)))
    geo, par, flag, atol, xi, kc, ks = arrays[4:11]
    if status != SETUP_OK:
        raise (ValueError if status in (SETUP_INTERFERENCE, SETUP_CONTACT_RATIO, SETUP_GRID,
                                        SETUP_TABLE) else np.linalg.LinAlgError)(
            setup_message(status, geo))
    n = int(flag[I_NTAB])
    nk = 4 * (n - 1) if flag[I_KIND] == KIND_CUBIC else n
    return Setup(geo, ModelData(par, flag, atol, xi[:n].copy(), kc[:nk].copy(),
                                ks[:n - 1].copy()))


def setup_message(status: int, geo: np.ndarray) -> str:
    """What a `SETUP_*` status means, for the user."""
    if status == SETUP_INTERFERENCE:
        return ("addendum_coef too large: the path of contact leaves the line of action "
                "(interference); allowed: tip circles that keep A and E between S1 and S2")
    if status == SETUP_CONTACT_RATIO:
        return (f"contact ratio {geo[GEO_EPS]:.3f} is below 1 (allowed >= 1): the gears "
                "cannot mesh continuously; raise addendum_coef or the tooth numbers")
    if status == SETUP_SPLINE:
        return "the potential-energy stiffness has no spline (a non-finite compliance)"
    if status == SETUP_MODES:
        return "the slip model's natural frequencies could not be computed"
    if status == SETUP_GRID:
        return ("FastEngine needs the stiffness table on a uniform grid from 0 to the path "
                "length (MeshStiffness.build makes one)")
    return f"a table law has {N_TABLE} points (set-up status {status})"


def tooth_compliances(p: GearParams, xi: np.ndarray, gear: int, *, root_segment: bool = True,
                      n_gauss: int = N_GAUSS, r_int: float | None = None) -> np.ndarray:
    """(4, len(xi)) bending, shear, axial and fillet-foundation compliances (m/N) of one
    tooth of gear ``gear`` (`tooth_compliance`); ValueError for gear data that interfere."""
    xi = np.ascontiguousarray(xi, dtype=float).ravel()
    out = np.zeros((xi.shape[0], 14))
    geo = np.zeros(N_GEO)
    opts = (bool(root_segment), math.nan if r_int is None else float(r_int),
            np.zeros(int(n_gauss)), np.zeros(int(n_gauss)))
    if compliances_entry(gear_vector(p), xi, np.int64(gear), opts, geo, out) \
            == SETUP_INTERFERENCE:
        raise ValueError(setup_message(SETUP_INTERFERENCE, geo))
    return out[:, :4].T.copy()


def geometry_vector(p: GearParams) -> np.ndarray:
    """The geometry (`GEO_*`) of gear data ``p`` (`setup` with the constant law and a given
    step bound: the geometry is all that is computed besides a few constants); ValueError
    for gear data that cannot mesh. The set-up's one entry point serves it, so a first run
    compiles no other for the geometry."""
    from ..effects import StiffnessSpec

    return run_setup(p, stiffness=StiffnessSpec("constant"),
                     options=FastOptions(max_step=1.0)).geo
