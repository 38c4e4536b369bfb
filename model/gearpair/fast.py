"""The fast engine: the reference engine's physics and switching rules, compiled with numba.

`FastEngine` implements the `Engine` contract with the same model (`equations.evaluate`), the
same switching rules (`switching`: Eq. (14) stick test, the paper-tie rule, slip directions
settled at entry and re-contact, the velocity projection at stick entry) and the same way of
taking a step as `reference.ReferenceEngine`:

- *known* discontinuities (a pair entering or leaving the path of contact; the pitch point
  for the nominal friction law) are segment boundaries computed from the mesh travel
  ``s = rb1 * speed * t``; the stored mesh energy that jumps there is booked as parametric
  work;
- inside a segment an embedded explicit Runge-Kutta pair integrates one contact state:
  DOP853, Dormand & Prince 8(5,3) with its continuous extension of order 7 (the default), or
  Dormand & Prince 5(4) with one of order 4 (``method="dp5"``); both with local
  extrapolation, FSAL, error control in the RMS norm of ``atol + rtol * |y|`` and the step
  bounded by ``max_step`` (half the period of the highest slip-model mode, as in the
  reference). DOP853 takes about a third of the steps at a tolerance that resolves the
  2.7-4 kHz mesh ringing (rtol 1e-7), which outweighs its twice as many stages;
- *unknown* switches are found by sampling the step at ``n_samples`` interior points (plus
  its end) and watching every event function for a fall through zero (DOP853 samples the
  cubic Hermite of the step ends first and re-scans on its full extension when something
  falls); the earliest fall is refined on the interpolant with the Illinois variant of
  regula falsi until the bracket is shorter than ``t_tol`` (default 1e-14 s plus 4 ulp of t);
  the located instant is the right end of the bracket (the state has already changed there).
  The state then switches and the integrator restarts from the located instant.

Everything on the hot path (`_advance` and what it calls) is ``numba.njit`` on flat
float64/int64 arrays: no Python objects, no allocation in the right-hand side (the work arrays
are allocated once per engine). Only this module and `jitcache` import numba; the package
works without it.

Compiled code is cached on disk, keyed by the content of the engine's source files rather than
their location (`jitcache`, which also provides the ``jit`` decorators).
"""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np

from .effects import Effects
from .engine import (
    CONTACT_BACK,
    CONTACT_SEPARATED,
    CONTACT_SLIP,
    CONTACT_STICK,
    Engine,
    Outputs,
    StepSummary,
    check_inputs,
)
from .equations import U2, Model
from .jitcache import jit, jit_inline
from .params import GearParams, check_rtol

# -- flat layout of the model data ---------------------------------------------------------
# float parameters (mp)
P_MINV, P_C, P_KB = 0, 6, 12
(P_RB1, P_RB2, P_RATIO, P_CM, P_MU, P_VEPS, P_S1A, P_S1S2, P_PB, P_L, P_PER, P_XIP, P_KMEAN,
 P_RTOL, P_MAXSTEP, P_TTOL, P_DX, P_INVDX, P_SPACING, P_IRB1, P_IRB2, P_IPER,
 P_BACK) = range(18, 41)
N_MP = 41
# int flags (mi)
(I_NP, I_KIND, I_VARY, I_SEP, I_FRIC, I_SLIDE, I_TIE, I_NSAMP, I_MAXEV, I_NTAB, I_BACK,
 I_TORS, I_LTI, I_METHOD, I_NIX) = range(15)
I_IX = 15  # mi[I_IX:I_IX + mi[I_NIX]]: the components of y the Runge-Kutta steps integrate
KIND_CONSTANT, KIND_TABLE, KIND_CUBIC = 0, 1, 2  # KIND_CUBIC: tk holds 4 spline coefficients
#                                                  per interval (`MeshStiffness.cubic`)
FR_OFF, FR_NOMINAL, FR_REG, FR_STICK = 0, 1, 2, 3
_FRICTION_CODE = {"off": FR_OFF, "nominal": FR_NOMINAL, "regularized": FR_REG,
                  "stick_slip": FR_STICK}
# per-pair work rows (pw)
W_XI, W_S1M, W_S2M, W_K, W_N, W_F, W_V, W_NOM, W_LAMEX, W_STK, W_DK = range(11)
N_PW = 11
# scalar work (sc): delta, ddelta, km, theta, F[6], qdd[6], compression (delta, delta + b on
# the back flank, 0 apart: the mesh force is km * compression)
S_DELTA, S_DDELTA, S_KM, S_THETA, S_F, S_QDD, S_COMP = 0, 1, 2, 3, 4, 10, 16
N_SC = 17
# continuous engine state (st) and discrete state (ist)
# T_SEP: no flank in contact (free flight); T_BACK: on the back flank (contact, not loss)
T_T, T_S, T_H, T_STICK, T_SEP, T_TORQUE, T_SPEED, T_REL, T_BACK = range(9)
N_ST = 9
# J_SEP: 0 drive flank, 1 apart, 2 back flank; J_REL: 1 + the pair released at time T_REL
J_SEP, J_NPREV, J_NEVTOT, J_REL = range(4)
N_IST = 4
N_Q = 6
N_Y = 18  # q, q', 4 energy quadratures (input, damping loss, friction work, parametric),
Y_A, Y_AD = 16, 17  # load-shaft end a (m, u2 coordinates) and its rate a' (held per step)
N_MI = I_IX + N_Y
# summary of one advance (out)
# O_NREJ: rejected steps; O_FINT: time integral of the mesh force over the advance (N s),
# O_FMIN: its least sample (as O_FMAX the peak)
O_FMAX, O_NEV, O_NSTEPS, O_STATUS, O_TFAIL, O_NREJ, O_FINT, O_FMIN = range(8)
N_OUT = 8
STATUS_OK, STATUS_EVENTS, STATUS_STEP = 0, 1, 2
# typical magnitudes for the default absolute tolerance (as the reference)
_SCALE = np.r_[np.full(6, 1e-5), np.full(6, 1e-3), np.full(4, 1.0), 1e-5, 1e-3]


def integrated_components(torsional: bool, friction: bool, varying: bool) -> np.ndarray:
    """Indices of the components of y that a Runge-Kutta step integrates.

    A switched-off effect leaves components whose rate is identically zero, and they are
    held: the error norm, the continuous extension and the event samples skip them. These
    are x1, x2 and their rates without friction (nothing else pushes along the off-line of
    action, so they stay at rest), all four support translations in the torsional model,
    the friction work without friction, the parametric power with a constant mesh
    stiffness, and always the load-shaft end's rate a' (held per step). Only the stage
    sums (`_stage`, `_hermite`) run over all N_Y components: there the held ones add exact
    zeros in SIMD lanes, which costs less than skipping them through this list.
    """
    keep = [2, 5, 8, 11, 12, 13, Y_A]  # u1, u2, their rates, input work, damping loss, a
    if not torsional:
        keep += [1, 4, 7, 10]  # y1, y2 along the line of action
        if friction:
            keep += [0, 3, 6, 9]  # x1, x2: driven only by the friction forces
    if friction:
        keep.append(14)
    if varying:
        keep.append(15)
    return np.array(sorted(keep), dtype=np.int64)


# Explicit Runge-Kutta pairs with a first-same-as-last stage, as tableaux of one shape so one
# compiled step serves both: Dormand & Prince 5(4) (7 stages, continuous extension of order 4
# by Hairer, Norsett & Wanner) and Dormand & Prince 8(5,3) (DOP853: 13 stages, 3 more for its
# order-7 continuous extension). DOP853's coefficients are read from scipy, which integrates
# with the same method, so the two can be compared number for number.
M_DP5, M_DOP853 = 0, 1
_METHOD_CODE = {"dp5": M_DP5, "dop853": M_DOP853}
RK_NK = 16  # stage rows of the work array K
_RK_NS = np.array([7, 13])  # stages of a step, the last at the new point (FSAL)
_RK_NX = np.array([7, 16])  # stages including the extra ones of the continuous extension
_RK_ND = np.array([1, 4])  # rows of D in the continuous extension
_RK_Q = np.array([5.0, 8.0])  # the error estimate is O(h^q): step factor err^(-1/q)
_RK_A = np.zeros((2, RK_NK, RK_NK))
_RK_C = np.zeros((2, RK_NK))
_RK_E = np.zeros((2, RK_NK))  # error weights (b - b_hat); DOP853: its 5th-order estimate
_RK_E3 = np.zeros((2, RK_NK))  # DOP853's 3rd-order estimate (zero for DP5)
_RK_D = np.zeros((2, 4, RK_NK))
_RK_C[0, :7] = [0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0]
_RK_A[0, 1, :1] = [1 / 5]
_RK_A[0, 2, :2] = [3 / 40, 9 / 40]
_RK_A[0, 3, :3] = [44 / 45, -56 / 15, 32 / 9]
_RK_A[0, 4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
_RK_A[0, 5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
_RK_A[0, 6, :6] = [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]
_RK_E[0, :7] = [71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40]
_RK_D[0, 0, :7] = [-12715105075 / 11282082432, 0.0, 87487479700 / 32700410799,
                   -10690763975 / 1880347072, 701980252875 / 199316789632,
                   -1453857185 / 822651844, 69997945 / 29380423]


def _load_dop853() -> None:
    from scipy.integrate._ivp import dop853_coefficients as d8

    _RK_A[1] = d8.A
    _RK_A[1, 12, :12] = d8.B  # the FSAL stage is evaluated at the new point
    _RK_C[1] = d8.C
    _RK_C[1, 11:13] = 1.0
    _RK_E[1, :13] = d8.E5
    _RK_E3[1, :13] = d8.E3
    _RK_D[1] = d8.D


_load_dop853()


# -- model functions (compiled) ------------------------------------------------------------
@jit_inline
def _sgn(x, fallback):
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return fallback


@jit_inline
def _wrap(x, per):
    """x mod per in [0, per) (numpy's mod for a positive divisor)."""
    r = x - per * math.floor(x * (1.0 / per))
    if r >= per:
        r -= per
    if r < 0.0:
        r = 0.0
    return r


@jit_inline
def _pair_xi(mp, s, j):
    """Position from A of tracked pair j held in contact at mesh travel s (Model.contact)."""
    per, L = mp[P_PER], mp[P_L]
    x = s + j * mp[P_PB]
    xi = x - per * math.floor(x * mp[P_IPER])
    if xi >= per:
        xi -= per
    if xi < 0.0:
        xi = 0.0
    if xi > 0.5 * (L + per):
        xi -= per
    return min(max(xi, 0.0), L)


@jit_inline
def _table_index(mp, mi, x):
    """Interval of the (uniform) stiffness table holding position x, clipped to the table."""
    i = int(math.floor(x * mp[P_INVDX]))
    return min(max(i, 0), mi[I_NTAB] - 2)


@jit_inline
def _pair_k(mp, mi, tx, tk, tdk, xi, xi_idx, nact):
    """Stiffness of a pair at xi, on the table interval that holds xi_idx (the same one
    over a step, so that a step ending on a knot uses the interval it integrated over)."""
    if mi[I_KIND] == KIND_CONSTANT:
        return mp[P_KMEAN] / max(nact, 1)
    i = _table_index(mp, mi, xi_idx)
    d = xi - tx[i]
    if mi[I_KIND] == KIND_CUBIC:
        c = 4 * i
        return ((tk[c + 3] * d + tk[c + 2]) * d + tk[c + 1]) * d + tk[c]
    return tk[i] + d * tdk[i]


@jit_inline
def _pair_kd(mp, mi, tx, tk, tdk, xi, xi_idx, nact, pw, i_pair):
    """`_pair_k`, also storing the slope d k/d xi in pw[W_DK]."""
    if mi[I_KIND] == KIND_CONSTANT:
        pw[W_DK, i_pair] = 0.0
        return mp[P_KMEAN] / max(nact, 1)
    i = _table_index(mp, mi, xi_idx)
    d = xi - tx[i]
    if mi[I_KIND] == KIND_CUBIC:
        c = 4 * i
        pw[W_DK, i_pair] = (3.0 * tk[c + 3] * d + 2.0 * tk[c + 2]) * d + tk[c + 1]
        return ((tk[c + 3] * d + tk[c + 2]) * d + tk[c + 1]) * d + tk[c]
    pw[W_DK, i_pair] = tdk[i]
    return tk[i] + d * tdk[i]


@jit
def _active_at(mp, mi, s, act):
    """Tracked pairs on the path of contact at s (0 <= xi < L); returns their number."""
    n = 0
    for j in range(mi[I_NP]):
        xi = _wrap(s + j * mp[P_PB], mp[P_PER])
        if 0.0 <= xi < mp[P_L]:
            act[n] = j
            n += 1
    return n


@jit
def _solve_small(Sm, n, nrhs):
    """Gaussian elimination with partial pivoting on Sm[:n, :n | n:n+nrhs], in place;
    solutions left in Sm[:n, n:n+nrhs]."""
    for c in range(n):
        p = c
        best = abs(Sm[c, c])
        for r in range(c + 1, n):
            if abs(Sm[r, c]) > best:
                best = abs(Sm[r, c])
                p = r
        if p != c:
            for k in range(n + nrhs):
                tmp = Sm[c, k]
                Sm[c, k] = Sm[p, k]
                Sm[p, k] = tmp
        piv = Sm[c, c]
        for r in range(c + 1, n):
            f = Sm[r, c] / piv
            if f != 0.0:
                for k in range(c, n + nrhs):
                    Sm[r, k] -= f * Sm[c, k]
    for r in range(n - 1, -1, -1):
        for k in range(n, n + nrhs):
            acc = Sm[r, k]
            for c in range(r + 1, n):
                acc -= Sm[r, c] * Sm[c, k]
            Sm[r, k] = acc / Sm[r, r]


@jit
def _evaluate(mp, mi, tx, tk, tdk, s, s_idx, y, torque, speed, act, nact, cs, dirs, stuck,
              pw, sc, Sm):
    """`equations.evaluate` for one contact state, into the work arrays ``pw`` / ``sc``.

    ``y`` holds q (0..5) and q' (6..11); ``dirs``/``stuck`` are over the tracked pairs;
    ``s_idx`` is the mesh travel that picks the stiffness-table interval (see `_pair_k`);
    ``cs`` is the contact code (0 drive flank, 1 apart, 2 back flank).
    """
    rb1, rb2, mu = mp[P_RB1], mp[P_RB2], mp[P_MU]
    irb1, irb2 = mp[P_IRB1], mp[P_IRB2]
    fric = mi[I_FRIC]
    full = mi[I_SLIDE] == 1
    km = 0.0
    for i in range(nact):
        xi = _pair_xi(mp, s, act[i])
        pw[W_XI, i] = xi
        s1m = mp[P_S1A] + xi
        pw[W_S1M, i] = s1m
        pw[W_S2M, i] = mp[P_S1S2] - s1m
        k = _pair_kd(mp, mi, tx, tk, tdk, xi, xi + (s_idx - s), nact, pw, i)
        pw[W_K, i] = k
        km += k
    delta = y[1] - y[4] + y[2] + y[5]
    ddelta = y[7] - y[10] + y[8] + y[11]
    theta = 0.0 if cs == 1 else 1.0
    comp = delta
    if cs == 1:
        comp = 0.0
    elif cs == 2:
        comp = delta + mp[P_BACK]
    sc[S_DELTA] = delta
    sc[S_DDELTA] = ddelta
    sc[S_KM] = km
    sc[S_THETA] = theta
    sc[S_COMP] = comp
    for m in range(6):
        sc[S_F + m] = -mp[P_C + m] * y[6 + m] - mp[P_KB + m] * y[m]
    gt = km * comp + theta * mp[P_CM] * ddelta
    sc[S_F + 1] -= gt
    sc[S_F + 2] -= gt
    sc[S_F + 4] += gt
    sc[S_F + 5] -= gt
    sc[S_F + 2] += torque * irb1
    sc[S_F + 5] += mp[P_KB + 5] * y[Y_A] + mp[P_C + 5] * y[Y_AD]  # load-shaft end
    ns = 0
    for i in range(nact):
        j = act[i]
        s1m, s2m = pw[W_S1M, i], pw[W_S2M, i]
        normal = pw[W_K, i] * delta if cs == 0 else 0.0  # friction on the drive flanks only
        pw[W_N, i] = normal
        nom = speed * (mp[P_RATIO] * s2m - s1m)
        pw[W_NOM, i] = nom
        if full:
            wq = -y[6] + s1m * irb1 * y[8] + y[9] + s2m * irb2 * y[11]
            v = nom - wq
        else:
            v = nom + y[6] - y[9]
        pw[W_V, i] = v
        f = 0.0
        pw[W_STK, i] = 0.0
        pw[W_LAMEX, i] = 0.0
        if fric == FR_NOMINAL:
            # the direction of the segment: nom moved to s_idx, which lies inside it (at a
            # pitch-point boundary nom is a rounding error from zero, its sign maybe the old)
            f = mu * abs(normal) * _sgn(nom - speed * (1.0 + mp[P_RATIO]) * (s_idx - s), 0.0)
        elif fric == FR_REG:
            f = mu * abs(normal) * math.tanh(v / mp[P_VEPS])
        elif fric == FR_STICK:
            if stuck[j] != 0:
                pw[W_STK, i] = 1.0
                ns += 1
            else:
                f = mu * abs(normal) * dirs[j]
        pw[W_F, i] = f
        if f != 0.0:
            sc[S_F + 0] -= f
            sc[S_F + 2] += f * s1m * irb1
            sc[S_F + 3] += f
            sc[S_F + 5] += f * s2m * irb2
    if mi[I_TORS] != 0:
        _pin_supports(sc)
    if ns > 0:
        # Static friction of the stuck pairs (equations.static_friction): rows a_a, columns
        # w_b; rhs -(c + a M^-1 F) for the chosen tie (col ns) and the exact tie (col ns+1).
        rate = -(1.0 + mp[P_RATIO]) * rb1 * speed * speed
        turn = 0.0
        if full:
            turn = -(speed * y[8] - rb1 * speed / rb2 * y[11])
        tr = 0.0 if mi[I_TORS] != 0 else 1.0
        ra = 0
        for ia in range(nact):
            if pw[W_STK, ia] == 0.0:
                continue
            wa2, wa5 = pw[W_S1M, ia] / rb1, pw[W_S2M, ia] / rb2
            rb = 0
            for ib in range(nact):
                if pw[W_STK, ib] == 0.0:
                    continue
                wb2, wb5 = pw[W_S1M, ib] / rb1, pw[W_S2M, ib] / rb2
                if full:  # a = -w; torsional: no x motion
                    Sm[ra, rb] = -(tr * (mp[P_MINV + 0] + mp[P_MINV + 3])
                                   + mp[P_MINV + 2] * wa2 * wb2 + mp[P_MINV + 5] * wa5 * wb5)
                else:     # a = [1, 0, 0, -1, 0, 0]
                    Sm[ra, rb] = -mp[P_MINV + 0] - mp[P_MINV + 3]
                rb += 1
            if full:
                aF = -(-mp[P_MINV + 0] * sc[S_F] + wa2 * mp[P_MINV + 2] * sc[S_F + 2]
                       + mp[P_MINV + 3] * sc[S_F + 3] + wa5 * mp[P_MINV + 5] * sc[S_F + 5])
            else:
                aF = mp[P_MINV + 0] * sc[S_F] - mp[P_MINV + 3] * sc[S_F + 3]
            c_tie = turn + (rate if mi[I_TIE] == 0 else 0.0)
            Sm[ra, ns] = -(c_tie + aF)
            Sm[ra, ns + 1] = -(turn + rate + aF)
            ra += 1
        _solve_small(Sm, ns, 2)
        ra = 0
        for i in range(nact):
            if pw[W_STK, i] == 0.0:
                continue
            lam = Sm[ra, ns]
            pw[W_F, i] = lam
            pw[W_LAMEX, i] = Sm[ra, ns + 1]
            s1m, s2m = pw[W_S1M, i], pw[W_S2M, i]
            sc[S_F + 0] -= lam
            sc[S_F + 2] += lam * s1m / rb1
            sc[S_F + 3] += lam
            sc[S_F + 5] += lam * s2m / rb2
            ra += 1
        if mi[I_TORS] != 0:
            _pin_supports(sc)
    for m in range(6):
        sc[S_QDD + m] = mp[P_MINV + m] * sc[S_F + m]


# The right-hand side (6 or 12 calls a Runge-Kutta step) gets its own inlined copy of the
# contact-state evaluation; the other callers share the compiled function (compile time).
_evaluate_inl = jit_inline(_evaluate.py_func)


@jit_inline
def _pin_supports(sc):
    """Torsional model: no forces on x1, y1, x2, y2 (rigid supports), which stay at 0."""
    sc[S_F + 0] = 0.0
    sc[S_F + 1] = 0.0
    sc[S_F + 3] = 0.0
    sc[S_F + 4] = 0.0


@jit_inline
def _n_sep_events(mi, cs):
    """Number of flank events: 1 (leave/regain contact), 2 apart with a back flank."""
    if mi[I_SEP] == 0:
        return 0
    return 2 if (cs == 1 and mi[I_BACK] != 0) else 1


@jit_inline
def _n_events(mi, nact, cs):
    n = _n_sep_events(mi, cs)
    if mi[I_FRIC] == FR_STICK and cs == 0:
        n += nact
    return n


@jit_inline
def _sep_event_values(mp, mi, cs, d, g):
    """Separation events of contact code ``cs`` at DTE ``d`` into g; returns their count."""
    if mi[I_SEP] == 0:
        return 0
    if cs == 0:
        g[0] = d
    elif cs == 2:
        g[0] = -(d + mp[P_BACK])
    else:
        g[0] = -d
        if mi[I_BACK] != 0:
            g[1] = d + mp[P_BACK]
    return _n_sep_events(mi, cs)


@jit_inline
def _event_values(mp, mi, nact, cs, act, dirs, pw, sc, g):
    """`switching.event_values`: positive while the state holds."""
    n = _sep_event_values(mp, mi, cs, sc[S_DELTA], g)
    if mi[I_FRIC] == FR_STICK and cs == 0:
        for i in range(nact):
            if pw[W_STK, i] != 0.0:
                lam = abs(pw[W_F, i])
                if mi[I_TIE] == 1:
                    lam = min(lam, abs(pw[W_LAMEX, i]))
                g[n] = mp[P_MU] * abs(pw[W_N, i]) - lam
            else:
                g[n] = dirs[act[i]] * pw[W_V, i]
            n += 1
    return n


@jit
def _param_rate(mp, mi, tdk, s_idx, y, act, nact, cs, speed):
    """Parametric power 0.5 (d km/dt) compression^2 on the table intervals at s_idx (W)."""
    if mi[I_VARY] == 0 or cs == 1:
        return 0.0
    dkm = 0.0
    for i in range(nact):
        dkm += tdk[_table_index(mp, mi, _pair_xi(mp, s_idx, act[i]))]
    delta = y[1] - y[4] + y[2] + y[5]
    if cs == 2:
        delta += mp[P_BACK]
    return 0.5 * dkm * mp[P_RB1] * speed * delta * delta


@jit
def _rhs(mp, mi, tx, tk, tdk, t, s_idx, y, t0, s0, torque, speed, act, nact, cs, dirs, stuck,
         pw, sc, Sm, dy):
    """Right-hand side of one contact state with the four energy quadratures."""
    rb1 = mp[P_RB1]
    s = s0 + rb1 * speed * (t - t0)
    _evaluate_inl(mp, mi, tx, tk, tdk, s, s_idx, y, torque, speed, act, nact, cs, dirs, stuck,
                  pw, sc, Sm)
    for m in range(6):
        dy[m] = y[6 + m]
        dy[6 + m] = sc[S_QDD + m]
    theta = sc[S_THETA]
    ad = y[Y_AD]
    dy[12] = torque * mp[P_IRB1] * y[8] - (mp[P_KB + 5] * (y[5] - y[Y_A])
                                           + mp[P_C + 5] * (y[11] - ad)) * ad
    d = 0.0
    for m in range(5):
        d += mp[P_C + m] * y[6 + m] * y[6 + m]
    d += mp[P_C + 5] * (y[11] - ad) * (y[11] - ad)
    dy[13] = d + theta * mp[P_CM] * sc[S_DDELTA] * sc[S_DDELTA]
    dy[Y_A] = ad
    dy[Y_AD] = 0.0
    pf = 0.0
    for i in range(nact):
        f = pw[W_F, i]
        if f != 0.0:
            wq = (-y[6] + pw[W_S1M, i] * mp[P_IRB1] * y[8] + y[9]
                  + pw[W_S2M, i] * mp[P_IRB2] * y[11])
            pf += f * wq
    dy[14] = pf
    if mi[I_VARY] != 0:
        dkm = 0.0
        for i in range(nact):
            dkm += pw[W_DK, i]
        dy[15] = 0.5 * dkm * rb1 * speed * sc[S_COMP] * sc[S_COMP]
    else:
        dy[15] = 0.0


# The Runge-Kutta stages call the right-hand side 6 or 12 times a step: there it is inlined
# (with the contact-state evaluation), which saves the by-value passing of some twenty arrays
# per call; elsewhere the compiled call keeps the kernels small.
_rhs_stage = jit_inline(_rhs.py_func)


@jit
def _next_knot_dt(mp, mi, s, speed, act, nact):
    """Time until an active pair reaches the next knot of the stiffness table (inf if none).

    A table law (linear) has a kink at every knot, a spline a jump in its third derivative;
    a Runge-Kutta step across one loses its order, so steps end on knots (the step sequence
    continues: the state is C^1 there).
    """
    if mi[I_VARY] == 0 or mi[I_NTAB] <= 2 or speed == 0.0:
        return np.inf
    dx, L = mp[P_DX], mp[P_L]
    v1 = mp[P_RB1] * speed
    guard = 1e-9 * dx
    best = np.inf
    for i in range(nact):
        xi = _pair_xi(mp, s, act[i])
        if speed > 0.0:
            knot = (math.floor(xi * mp[P_INVDX]) + 1.0) * dx
            if knot - xi <= guard:
                knot += dx
            if knot >= L - guard:
                continue
        else:
            knot = (math.ceil(xi * mp[P_INVDX]) - 1.0) * dx
            if xi - knot <= guard:
                knot -= dx
            if knot <= guard:
                continue
        dt = (knot - xi) / v1
        if dt < best:
            best = dt
    return best


@jit
def _settle(mp, mi, s, y, speed, act, nact, cs, dirs, stuck):
    """`switching.settle_directions`: slip direction of slipping pairs from their velocity."""
    if mi[I_FRIC] != FR_STICK or cs != 0:
        return
    for i in range(nact):
        j = act[i]
        if stuck[j] == 0:
            dirs[j] = _sgn(_pair_v(mp, mi, s, y, speed, j), dirs[j])


@jit_inline
def _pair_v(mp, mi, s, y, speed, j):
    xi = _pair_xi(mp, s, j)
    s1m = mp[P_S1A] + xi
    s2m = mp[P_S1S2] - s1m
    nom = speed * (mp[P_RATIO] * s2m - s1m)
    if mi[I_SLIDE] == 1:  # the arithmetic of `_evaluate`, to the last bit
        return nom - (-y[6] + s1m * mp[P_IRB1] * y[8] + y[9] + s2m * mp[P_IRB2] * y[11])
    return nom + y[6] - y[9]


@jit
def _switch(mp, mi, tx, tk, tdk, label, s, y, torque, speed, act, nact, ist, dirs, stuck,
            trial, pw, sc, Sm):
    """`switching.switch`: apply event ``label`` (index into the event functions)."""
    cs = ist[J_SEP]
    nsep = _n_sep_events(mi, cs)
    if label < nsep:
        if cs == 0:      # drive flanks separate
            ist[J_SEP] = 1
            for j in range(mi[I_NP]):
                stuck[j] = 0
        elif cs == 2:    # back flanks separate
            ist[J_SEP] = 1
        elif label == 1:  # apart -> back flank contact
            ist[J_SEP] = 2
        else:            # apart -> drive flank contact
            ist[J_SEP] = 0
            _settle(mp, mi, s, y, speed, act, nact, 0, dirs, stuck)
        return
    i = label - nsep
    j = act[i]
    if stuck[j] != 0:
        _evaluate(mp, mi, tx, tk, tdk, s, s, y, torque, speed, act, nact, cs, dirs, stuck, pw,
                  sc, Sm)
        stuck[j] = 0
        dirs[j] = _sgn(pw[W_LAMEX, i], 1.0)
        ist[J_REL] = j + 1  # the caller records the time in st[T_REL]
        return
    # Eq. (14) stick test with the pair tentatively stuck
    for jj in range(mi[I_NP]):
        trial[jj] = stuck[jj]
    trial[j] = 1
    _evaluate(mp, mi, tx, tk, tdk, s, s, y, torque, speed, act, nact, cs, dirs, trial, pw, sc,
              Sm)
    lam = abs(pw[W_F, i])
    lam_e = pw[W_LAMEX, i]
    if mi[I_TIE] == 1:
        lam = min(lam, abs(lam_e))
    if lam <= mp[P_MU] * abs(pw[W_N, i]):
        stuck[j] = 1
        y[6 + 3] += _pair_v(mp, mi, s, y, speed, j)  # d v_j / d x2' = -1: v_j -> 0
    else:
        dirs[j] = _sgn(lam_e, 1.0)


@jit_inline
def _interp(mi, R, nf, theta, out):
    """Continuous extension of the accepted step at fraction ``theta``:
    R0 + th (R1 + (1 - th) (R2 + th (R3 + ...))) over rows 1..nf; the components that are
    not integrated (`integrated_components`) are left as they are in ``out``."""
    th1 = 1.0 - theta
    for k in range(mi[I_NIX]):
        m = mi[I_IX + k]
        acc = 0.0
        for i in range(nf, 0, -1):
            acc = (R[i, m] + acc) * (theta if i % 2 == 1 else th1)
        out[m] = R[0, m] + acc


R_GSAVE, R_GEND = 8, 9  # rows of the work array R: event values at a step's start and end
R_FSTG = 10  # row of R: the mesh force at each Runge-Kutta stage of the current step
# Gauss-Legendre nodes and weights on [0, 1] (3 points, exact to degree 5): the mesh force
# integral over a step cut short by an event, on its continuous extension
_GL3_X = np.array([0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6)])
_GL3_W = np.array([5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0])


@jit_inline
def _hermite(R, y, ynew, K, hh, nfs):
    """Rows 0-3 of the continuous extension (`_interp`): alone, the cubic Hermite of the step
    ends (K[0] at the start, K[nfs] at the end); returns its row count."""
    for m in range(N_Y):
        dyn = ynew[m] - y[m]
        R[0, m] = y[m]
        R[1, m] = dyn
        R[2, m] = hh * K[0, m] - dyn
        R[3, m] = 2.0 * dyn - hh * (K[0, m] + K[nfs, m])
    return 3


@jit_inline
def _dense(mi, meth, R, y, ynew, K, hh):
    """Coefficients of the continuous extension of the step y -> ynew (for `_interp`): the
    Hermite rows plus rows of D; for DOP853 the extra stages must be in K already
    (`_extend`). Returns the row count."""
    _hermite(R, y, ynew, K, hh, _RK_NS[meth] - 1)
    nx = _RK_NX[meth]
    nd = _RK_ND[meth]
    for k in range(mi[I_NIX]):
        m = mi[I_IX + k]
        for r in range(nd):
            acc = 0.0
            for j in range(nx):
                acc += _RK_D[meth, r, j] * K[j, m]
            R[4 + r, m] = hh * acc
    return 3 + nd


@jit_inline
def _err_norm(mi, meth, yold, ynew, K, hh, atol, rtol):
    """Weighted RMS norm of the local error estimate (DOP853: Hairer's blend of its 5th- and
    3rd-order estimates, which keeps the step from growing where the 5th-order one vanishes
    by chance).

    The mean is over all N_Y components, the held ones contributing their exact zero: the
    step sequence does not depend on whether a component whose rate vanishes is integrated
    (friction off steps as friction with mu = 0)."""
    ns = _RK_NS[meth]
    blend = meth == M_DOP853  # DP5 has no 3rd-order estimate
    a5 = 0.0
    a3 = 0.0
    for k in range(mi[I_NIX]):
        m = mi[I_IX + k]
        sk = atol[m] + rtol * max(abs(yold[m]), abs(ynew[m]))
        e5 = 0.0
        e3 = 0.0
        for j in range(ns):
            e5 += _RK_E[meth, j] * K[j, m]
            if blend:
                e3 += _RK_E3[meth, j] * K[j, m]
        e5 /= sk
        e3 /= sk
        a5 += e5 * e5
        a3 += e3 * e3
    if not blend:
        return hh * math.sqrt(a5 / N_Y)
    if a5 == 0.0:
        return 0.0
    return hh * a5 / math.sqrt((a5 + 0.01 * a3) * N_Y)


@jit
def _initial_step(mp, mi, tx, tk, tdk, t0, y, f0, s0, torque, speed, act, nact, sep, dirs,
                  stuck, pw, sc, Sm, atol, ytmp, ftmp, t_lim):
    """Starting step from the size of y, y' and y'' (Hairer, Norsett & Wanner, II.4)."""
    rtol = mp[P_RTOL]
    d0 = 0.0
    d1 = 0.0
    for m in range(N_Y):
        sk = atol[m] + rtol * abs(y[m])
        d0 += (y[m] / sk) ** 2
        d1 += (f0[m] / sk) ** 2
    d0 = math.sqrt(d0 / N_Y)
    d1 = math.sqrt(d1 / N_Y)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, t_lim - t0, mp[P_MAXSTEP])
    for m in range(N_Y):
        ytmp[m] = y[m] + h0 * f0[m]
    s_idx = s0 + mp[P_RB1] * speed * 0.5 * h0
    _rhs(mp, mi, tx, tk, tdk, t0 + h0, s_idx, ytmp, t0, s0, torque, speed, act, nact, sep,
         dirs, stuck, pw, sc, Sm, ftmp)
    d2 = 0.0
    for m in range(N_Y):
        sk = atol[m] + rtol * abs(y[m])
        d2 += ((ftmp[m] - f0[m]) / sk) ** 2
    d2 = math.sqrt(d2 / N_Y) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / _RK_Q[mi[I_METHOD]])
    return min(100.0 * h0, h1, mp[P_MAXSTEP])


@jit
def _events_at(mp, mi, tx, tk, tdk, t, yk, t0, s0, torque, speed, act, nact, sep, dirs,
               stuck, pw, sc, Sm, g):
    s = s0 + mp[P_RB1] * speed * (t - t0)
    _evaluate(mp, mi, tx, tk, tdk, s, s, yk, torque, speed, act, nact, sep, dirs, stuck, pw,
              sc, Sm)
    _event_values(mp, mi, nact, sep, act, dirs, pw, sc, g)
    return sc[S_KM] * sc[S_COMP]


@jit
def _events_light(mp, mi, tx, tk, tdk, t, yk, t0, s0, torque, speed, act, nact, sep, dirs,
                  stuck, pw, sc, Sm, g):
    """`_events_at` where no pair is stuck: the event functions (DTE, slip velocities) and
    the mesh force are then plain expressions of the state, so the forces, the friction and
    the accelerations are not evaluated (the samples inside a step need only these)."""
    if mi[I_FRIC] == FR_STICK and sep == 0 and _any_stuck(mi, stuck):
        return _events_at(mp, mi, tx, tk, tdk, t, yk, t0, s0, torque, speed, act, nact, sep,
                          dirs, stuck, pw, sc, Sm, g)
    s = s0 + mp[P_RB1] * speed * (t - t0)
    delta = yk[1] - yk[4] + yk[2] + yk[5]
    n = _sep_event_values(mp, mi, sep, delta, g)
    if mi[I_FRIC] == FR_STICK and sep == 0:
        for i in range(nact):
            g[n + i] = dirs[act[i]] * _pair_v(mp, mi, s, yk, speed, act[i])
    if sep == 1:
        return 0.0
    km = 0.0
    for i in range(nact):
        xi = _pair_xi(mp, s, act[i])
        km += _pair_k(mp, mi, tx, tk, tdk, xi, xi, nact)
    return km * (delta + mp[P_BACK] if sep == 2 else delta)


@jit
def _book(mi, st, sep, stuck, dt):
    if sep == 1:  # no flank in contact
        st[T_SEP] += dt
    elif sep == 2:  # on the back flank: contact, not contact loss
        st[T_BACK] += dt
    elif _any_stuck(mi, stuck):
        st[T_STICK] += dt


@jit_inline
def _illinois_point(a, ga, b, gb):
    """Next point of the Illinois (modified regula falsi) search on [a, b], g(a) > 0 >= g(b)."""
    c = b - gb * (b - a) / (gb - ga)
    if not (a < c < b):
        c = 0.5 * (a + b)
    return c


@jit_inline
def _illinois(a, ga, b, gb, c, gc, side):
    """Shrink the bracket with the value gc at c; halve the stale end's value when the same
    end moves twice (what keeps regula falsi superlinear). Returns a, ga, b, gb, side."""
    if gc <= 0.0:
        if side == -1:
            ga *= 0.5
        return a, ga, c, gc, -1
    if side == 1:
        gb *= 0.5
    return c, gc, b, gb, 1


# -- exact propagator for constant-coefficient pieces ------------------------------------------
# With friction off and constant or rectangular stiffness, a piece (one contact state, one pair
# set, inputs held) is the linear time-invariant system z' = A z with
# z = [q, q', a, a', torque, 1, integral of u2]: the torque and the constant are states with
# zero rate so that A does not depend on the inputs. Then z(t + h) = expm(A h) z(t) exactly:
# the 2.7-4 kHz ringing that an explicit method must resolve step by step costs nothing.
NZ = 17
Z_A, Z_AD, Z_TQ, Z_ONE, Z_IU2 = 12, 13, 14, 15, 16
L_NSLOT = 12  # cached propagators, keyed by (contact code, total stiffness, step)
L_SCRATCH = 2 * L_NSLOT  # Lm[:L_NSLOT]: A of a slot; Lm[L_NSLOT:L_SCRATCH]: its expm(A h)
_PADE6 = np.array([math.factorial(12 - k) * math.factorial(6)
                   / (math.factorial(12) * math.factorial(k) * math.factorial(6 - k))
                   for k in range(7)])


@jit_inline
def _mm(A, B, C):
    """C = A B (NZ x NZ)."""
    for i in range(NZ):
        for j in range(NZ):
            C[i, j] = 0.0
        for k in range(NZ):
            a = A[i, k]
            if a != 0.0:
                for j in range(NZ):
                    C[i, j] += a * B[k, j]


@jit
def _expm(A, h, E, S):
    """E = expm(A h): power-of-two balancing, scaling and squaring, diagonal Pade (6, 6)
    (truncation error below 1e-19 at the scaled norm 0.5). ``S``: scratch (12 matrices; 8
    and 9 are left alone for the caller)."""
    X, X2, X4, X6, U, V, T = S[0], S[1], S[2], S[3], S[4], S[5], S[6]
    d = S[7][0]
    for i in range(NZ):
        d[i] = 1.0
        for j in range(NZ):
            X[i, j] = A[i, j] * h
    # X <- D^-1 X D with D = diag(d), powers of two (LAPACK gebal without permutations)
    for _sweep in range(30):
        done = True
        for i in range(NZ):
            c = 0.0
            r = 0.0
            for j in range(NZ):
                if j != i:
                    c += abs(X[j, i])
                    r += abs(X[i, j])
            if c == 0.0 or r == 0.0:
                continue
            s0 = c + r
            f = 1.0
            while c < 0.5 * r:
                c *= 2.0
                r *= 0.5
                f *= 2.0
            while c >= 2.0 * r:
                c *= 0.5
                r *= 2.0
                f *= 0.5
            if c + r < 0.95 * s0:
                done = False
                d[i] *= f
                for j in range(NZ):
                    X[i, j] /= f
                    X[j, i] *= f
        if done:
            break
    nrm = 0.0
    for j in range(NZ):
        acc = 0.0
        for i in range(NZ):
            acc += abs(X[i, j])
        nrm = max(nrm, acc)
    sq = 0
    while nrm > 0.5 and sq < 200:
        nrm *= 0.5
        sq += 1
    sc_ = 0.5 ** sq
    for i in range(NZ):
        for j in range(NZ):
            X[i, j] *= sc_
    _mm(X, X, X2)
    _mm(X2, X2, X4)
    _mm(X4, X2, X6)
    c = _PADE6
    for i in range(NZ):
        for j in range(NZ):
            T[i, j] = c[3] * X2[i, j] + c[5] * X4[i, j]
            V[i, j] = c[2] * X2[i, j] + c[4] * X4[i, j] + c[6] * X6[i, j]
        T[i, i] += c[1]
        V[i, i] += c[0]
    _mm(X, T, U)
    for i in range(NZ):
        for j in range(NZ):
            E[i, j] = V[i, j] + U[i, j]   # numerator
            V[i, j] = V[i, j] - U[i, j]   # denominator
    # solve V R = E (partial pivoting), R into E
    Wd = S[10:12].reshape((NZ, 2 * NZ))
    for i in range(NZ):
        for j in range(NZ):
            Wd[i, j] = V[i, j]
            Wd[i, NZ + j] = E[i, j]
    _solve_small(Wd, NZ, NZ)
    for i in range(NZ):
        for j in range(NZ):
            E[i, j] = Wd[i, NZ + j]
    for _ in range(sq):
        _mm(E, E, T)
        for i in range(NZ):
            for j in range(NZ):
                E[i, j] = T[i, j]
    for i in range(NZ):
        for j in range(NZ):
            E[i, j] *= d[i] / d[j]


@jit_inline
def _z_to_y(z, y):
    for m in range(12):
        y[m] = z[m]
    y[Y_A] = z[Z_A]
    y[Y_AD] = z[Z_AD]


@jit
def _lti_matrix(mp, mi, tx, tk, tdk, t0, s0, speed, act, nact, cs, dirs, stuck, pw, sc, Sm,
                ytmp, dy, A):
    """A of the piece by probing the (affine) right-hand side: the same physics as the
    Runge-Kutta path, column by column."""
    for i in range(NZ):
        for j in range(NZ):
            A[i, j] = 0.0
    for m in range(N_Y):
        ytmp[m] = 0.0
    _rhs(mp, mi, tx, tk, tdk, t0, s0, ytmp, t0, s0, 0.0, speed, act, nact, cs, dirs, stuck,
         pw, sc, Sm, dy)
    for r in range(12):
        A[r, Z_ONE] = dy[r]
    A[Z_A, Z_ONE] = dy[Y_A]
    for c in range(Z_ONE):
        for m in range(N_Y):
            ytmp[m] = 0.0
        tq = 0.0
        if c < 12:
            ytmp[c] = 1.0
        elif c == Z_A:
            ytmp[Y_A] = 1.0
        elif c == Z_AD:
            ytmp[Y_AD] = 1.0
        else:
            tq = 1.0
        _rhs(mp, mi, tx, tk, tdk, t0, s0, ytmp, t0, s0, tq, speed, act, nact, cs, dirs, stuck,
             pw, sc, Sm, dy)
        for r in range(12):
            A[r, c] = dy[r] - A[r, Z_ONE]
        A[Z_A, c] = dy[Y_A] - A[Z_A, Z_ONE]
    A[Z_IU2, 5] = 1.0


@jit
def _lti_slot(mp, mi, tx, tk, tdk, t0, s0, speed, act, nact, cs, km, h, dirs, stuck, pw, sc,
              Sm, ytmp, dy, Lm, Lk):
    """Index of the cached propagator for (cs, km, h); built on a miss (least recently
    used slot). Keys match exactly: what a step computes must not depend on what the cache
    saw before (a state restored into a fresh engine continues bit for bit). A grid's
    round-off makes only a few distinct step lengths, which the slots hold."""
    Lk[L_NSLOT, 0] += 1.0
    use = Lk[L_NSLOT, 0]
    same_a = -1
    for k in range(L_NSLOT):
        if Lk[k, 0] == cs and Lk[k, 1] == km:
            if Lk[k, 2] == h:
                Lk[k, 3] = use
                return k
            same_a = k
    k_new = 0
    for k in range(1, L_NSLOT):
        if Lk[k, 3] < Lk[k_new, 3]:
            k_new = k
    if same_a >= 0:
        if same_a != k_new:
            for i in range(NZ):
                for j in range(NZ):
                    Lm[k_new, i, j] = Lm[same_a, i, j]
    else:
        _lti_matrix(mp, mi, tx, tk, tdk, t0, s0, speed, act, nact, cs, dirs, stuck, pw, sc,
                    Sm, ytmp, dy, Lm[k_new])
    _expm(Lm[k_new], h, Lm[L_NSLOT + k_new], Lm[L_SCRATCH:])
    Lk[k_new, 0], Lk[k_new, 1], Lk[k_new, 2], Lk[k_new, 3] = cs, km, h, use
    return k_new


@jit
def _lti_quiet(mp, mi, A, z, cs, W):
    """True when the piece provably stays in its contact state with the mesh force within
    rtol of its static value: then it needs no sampling for events or the peak force.

    The deviation e from the static equilibrium of a passive system with constant
    coefficients has non-increasing energy E = e'^T M e' / 2 + e^T K e / 2, so
    |g . e| <= sqrt(2 E g^T K^-1 g) for the whole piece. Needs K positive definite (in mesh)
    and a load-shaft end at rest (a' = 0).
    """
    if cs == 1 or z[Z_AD] != 0.0:
        return False
    nf = 2 if mi[I_TORS] != 0 else 6
    # free coordinates: u1, u2 (torsional) or all six
    for a in range(nf):
        ia = (2, 5)[a] if nf == 2 else a
        for b in range(nf):
            ib = (2, 5)[b] if nf == 2 else b
            W[a, b] = -A[6 + ia, ib] / mp[P_MINV + ia]
        # static force: a, torque and the constant at q = q' = 0
        W[a, nf] = (A[6 + ia, Z_A] * z[Z_A] + A[6 + ia, Z_TQ] * z[Z_TQ]
                    + A[6 + ia, Z_ONE]) / mp[P_MINV + ia]
        W[a, nf + 1] = (0.0, 1.0, 1.0, 0.0, -1.0, 1.0)[ia]  # g
    # Cholesky K = L L^T in place (lower), then two right-hand sides
    for j in range(nf):
        acc = W[j, j]
        for k in range(j):
            acc -= W[j, k] * W[j, k]
        if not (acc > 0.0):
            return False
        ljj = math.sqrt(acc)
        W[j, j] = ljj
        for i in range(j + 1, nf):
            acc = W[i, j]
            for k in range(j):
                acc -= W[i, k] * W[j, k]
            W[i, j] = acc / ljj
    for c in range(nf, nf + 2):
        for i in range(nf):
            acc = W[i, c]
            for k in range(i):
                acc -= W[i, k] * W[k, c]
            W[i, c] = acc / W[i, i]
        for i in range(nf - 1, -1, -1):
            acc = W[i, c]
            for k in range(i + 1, nf):
                acc -= W[k, i] * W[k, c]
            W[i, c] = acc / W[i, i]
    # W[:, nf] = q_p (free part), W[:, nf + 1] = K^-1 g
    gkg = 0.0
    comp_p = 0.0
    energy = 0.0
    for a in range(nf):
        ia = (2, 5)[a] if nf == 2 else a
        ga = (0.0, 1.0, 1.0, 0.0, -1.0, 1.0)[ia]
        gkg += ga * W[a, nf + 1]
        comp_p += ga * W[a, nf]
        energy += 0.5 * z[6 + ia] * z[6 + ia] / mp[P_MINV + ia]
    if cs == 2:
        comp_p += mp[P_BACK]
    # e^T K e from K = -M A (rows of the free coordinates), e = q - q_p
    for a in range(nf):
        ia = (2, 5)[a] if nf == 2 else a
        ka = 0.0
        for b in range(nf):
            ib = (2, 5)[b] if nf == 2 else b
            ka += -A[6 + ia, ib] / mp[P_MINV + ia] * (z[ib] - W[b, nf])
        energy += 0.5 * (z[ia] - W[a, nf]) * ka
    bound = math.sqrt(max(2.0 * energy * gkg, 0.0))
    if cs == 0:
        return comp_p > 0.0 and bound <= mp[P_RTOL] * comp_p
    return comp_p < 0.0 and bound <= -mp[P_RTOL] * comp_p


@jit_inline
def _comp_of(mp, z, cs):
    if cs == 1:
        return 0.0
    d = z[1] - z[4] + z[2] + z[5]
    return d + mp[P_BACK] if cs == 2 else d


@jit_inline
def _stored_change(mp, z0, z1, km, cs):
    """Stored energy at z1 minus at z0 (J): kinetic, supports, load shaft, mesh spring (as
    `energy`), each as k (x1 - x0)(x1 + x0) / 2 so that a small change of a large stored
    energy keeps its relative accuracy."""
    de = 0.0
    for m in range(6):
        if mp[P_MINV + m] > 0.0:
            de += 0.5 / mp[P_MINV + m] * (z1[6 + m] - z0[6 + m]) * (z1[6 + m] + z0[6 + m])
        de += 0.5 * mp[P_KB + m] * (z1[m] - z0[m]) * (z1[m] + z0[m])
    # load shaft: kr2 (u2 - a)^2 / 2 replaces the kr2 u2^2 / 2 counted above
    e0, e1 = z0[5] - z0[Z_A], z1[5] - z1[Z_A]
    de += 0.5 * mp[P_KB + 5] * ((e1 - e0) * (e1 + e0) - (z1[5] - z0[5]) * (z1[5] + z0[5]))
    c0, c1 = _comp_of(mp, z0, cs), _comp_of(mp, z1, cs)
    return de + 0.5 * km * (c1 - c0) * (c1 + c0)


@jit
def _lti_finish(mp, y, z0, z1, dt, km, cs):
    """State z1 into y, with the input work and the damping loss of the stretch from z0:
    input = torque/rb1 du1 - a' (kr2 int(u2 - a) + cr2 int(u2' - a')). No friction or
    parametric power acts here, so the damping loss is the input work minus the change of
    stored energy (exact for the exact solution; a negative rounding residue is dropped, the
    loss of a passive damper cannot be)."""
    tq, ad = z0[Z_TQ], z0[Z_AD]
    int_a = z0[Z_A] * dt + 0.5 * ad * dt * dt
    w_in = tq * mp[P_IRB1] * (z1[2] - z0[2]) - ad * (
        mp[P_KB + 5] * (z1[Z_IU2] - z0[Z_IU2] - int_a) + mp[P_C + 5] * (z1[5] - z0[5] - ad * dt))
    y[12] += w_in
    y[13] += max(w_in - _stored_change(mp, z0, z1, km, cs), 0.0)
    _z_to_y(z1, y)


@jit_inline
def _lti_dd(A, z):
    """delta'' = g . q'' of the exact solution at z (rows of A z)."""
    acc = 0.0
    for m in range(NZ):
        acc += (A[7, m] - A[10, m] + A[8, m] + A[11, m]) * z[m]
    return acc


@jit_inline
def _lti_fint(mp, A, z0, z1, h, km, cs, quiet):
    """Time integral (N s) of the mesh force km * compression over an exact stretch z0 -> z1
    of h seconds (A: the stretch's z' = A z): the two-point Hermite rule with the force and
    its first two derivatives at both ends, h/2 (f0 + f1) + h^2/10 (f0' - f1') +
    h^3/120 (f0" + f1"), exact to degree 5 (error O(h^7): about 1e-8 of the force's swing at
    the sample spacing, 1/18 of the fastest mode's period). A quiet stretch (`_lti_quiet`:
    the force stays within rtol of its static value, however long the stretch) takes the
    trapezoid, whose error is below that bound."""
    if cs == 1:
        return 0.0
    trap = 0.5 * h * km * (_comp_of(mp, z0, cs) + _comp_of(mp, z1, cs))
    if quiet:
        return trap
    d0 = z0[7] - z0[10] + z0[8] + z0[11]
    d1 = z1[7] - z1[10] + z1[8] + z1[11]
    dd = _lti_dd(A, z0) + _lti_dd(A, z1)
    return trap + km * h * h * ((d0 - d1) / 10.0 + h * dd / 120.0)


@jit_inline
def _mv(P, z, out):
    for i in range(NZ):
        acc = 0.0
        for j in range(NZ):
            acc += P[i, j] * z[j]
        out[i] = acc


# inlined into its single caller `_piece`: the call alone (some 25 arrays by value) was a
# tenth of a quiet constant-coefficient output point
@jit_inline
def _piece_lti(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, trial, act, nact, tb, ytmp, g,
               gprev, pw, sc, Sm, Lm, Lk, Lv, out):
    """`_piece` for constant coefficients: exact steps z <- expm(A h) z. A quiet piece
    (`_lti_quiet`) is one step; otherwise steps of at most the sample spacing are scanned for
    falls through zero, refined by Illinois on the exact solution."""
    eps = 2.220446049250313e-16
    t0, s0 = st[T_T], st[T_S]
    torque, speed = st[T_TORQUE], st[T_SPEED]
    v1 = mp[P_RB1] * speed
    cs = ist[J_SEP]
    ng = _n_events(mi, nact, cs)
    km = 0.0
    for i in range(nact):
        xi = _pair_xi(mp, s0, act[i])
        km += _pair_k(mp, mi, tx, tk, tdk, xi, xi, nact)
    htot = tb - t0
    if not (htot > 16.0 * eps * max(abs(t0), 1e-300)):
        _book(mi, st, cs, stuck, htot)
        st[T_S] = s0 + v1 * htot
        st[T_T] = tb
        return 0
    z, zn, zs, zc, gc = Lv[0], Lv[1], Lv[2], Lv[3], Lv[4]
    for m in range(12):
        z[m] = y[m]
    z[Z_A], z[Z_AD], z[Z_TQ], z[Z_ONE], z[Z_IU2] = y[Y_A], y[Y_AD], torque, 1.0, 0.0
    for m in range(NZ):
        zs[m] = z[m]
    W, E = Lm[L_SCRATCH + 8], Lm[L_SCRATCH + 9]
    k = _lti_slot(mp, mi, tx, tk, tdk, t0, s0, speed, act, nact, cs, km, htot, dirs, stuck, pw,
                  sc, Sm, ytmp, Lv[5], Lm, Lk)
    nsub = 1
    quiet = _lti_quiet(mp, mi, Lm[k], z, cs, W)
    if quiet:  # no event can fall: the start's force is all that is needed of it
        fm = km * _comp_of(mp, z, cs)
    else:
        fm = _events_at(mp, mi, tx, tk, tdk, t0, y, t0, s0, torque, speed, act, nact, cs,
                        dirs, stuck, pw, sc, Sm, gprev)
    if fm > out[O_FMAX]:
        out[O_FMAX] = fm
    if fm < out[O_FMIN]:
        out[O_FMIN] = fm
    if not quiet:
        nsub = max(1, int(math.ceil(htot / mp[P_SPACING] * (1.0 - 1e-12))))
        if nsub > 1:
            k = _lti_slot(mp, mi, tx, tk, tdk, t0, s0, speed, act, nact, cs, km, htot / nsub,
                          dirs, stuck, pw, sc, Sm, ytmp, Lv[5], Lm, Lk)
    hs = htot / nsub
    t = t0
    ks = 0
    while ks < nsub:
        ks += 1
        jumped = False
        if ks % 256 == 0 and ks < nsub and _lti_quiet(mp, mi, Lm[k], z, cs, W):
            # the transient has died out: one exact step to the end
            kq = _lti_slot(mp, mi, tx, tk, tdk, t0, s0, speed, act, nact, cs, km, tb - t,
                           dirs, stuck, pw, sc, Sm, ytmp, Lv[5], Lm, Lk)
            _mv(Lm[L_NSLOT + kq], z, zn)
            ks = nsub
            jumped = True
        else:
            _mv(Lm[L_NSLOT + k], z, zn)
        tn = tb if ks == nsub else t0 + ks * hs
        out[O_NSTEPS] += 1.0
        if quiet:
            # one step: no event can fall, and the force at the end is the next piece's
            # start or the step's outputs, which the step's peak includes
            out[O_FINT] += _lti_fint(mp, Lm[k], z, zn, tn - t, km, cs, True)
            for m in range(NZ):
                z[m] = zn[m]
            t = tn
            continue
        _z_to_y(zn, ytmp)
        fm = _events_at(mp, mi, tx, tk, tdk, tn, ytmp, t0, s0, torque, speed, act, nact, cs,
                        dirs, stuck, pw, sc, Sm, g)
        hit = False
        for e in range(ng):
            if gprev[e] > 0.0 and g[e] <= 0.0:
                hit = True
        if not hit:
            if fm > out[O_FMAX]:
                out[O_FMAX] = fm
            if fm < out[O_FMIN]:
                out[O_FMIN] = fm
            out[O_FINT] += _lti_fint(mp, Lm[k], z, zn, tn - t, km, cs, jumped)
            for m in range(NZ):
                z[m] = zn[m]
            for e in range(ng):
                gprev[e] = g[e]
            t = tn
            continue
        # Illinois on [t, tn] with the exact solution; the earliest falling function wins
        h = tn - t
        best_tau = h
        best_e = -1
        tol = mp[P_TTOL] + 8.0 * eps * abs(t)
        for e in range(ng):
            if not (gprev[e] > 0.0 and g[e] <= 0.0):
                continue
            a, ga = 0.0, gprev[e]
            b, gb = h, g[e]
            side = 0
            for _it in range(200):
                if b - a <= tol:
                    break
                c = _illinois_point(a, ga, b, gb)
                _expm(Lm[k], c, E, Lm[L_SCRATCH:])
                _mv(E, z, zc)
                _z_to_y(zc, ytmp)
                _events_at(mp, mi, tx, tk, tdk, t + c, ytmp, t0, s0, torque, speed, act,
                           nact, cs, dirs, stuck, pw, sc, Sm, gc)
                a, ga, b, gb, side = _illinois(a, ga, b, gb, c, gc[e], side)
            if best_e < 0 or b < best_tau:
                best_tau, best_e = b, e
        te = tn
        if best_tau < h:
            te = t + best_tau
            _expm(Lm[k], best_tau, E, Lm[L_SCRATCH:])
            _mv(E, z, zn)
        out[O_FINT] += _lti_fint(mp, Lm[k], z, zn, te - t, km, cs, jumped)
        _lti_finish(mp, y, zs, zn, te - t0, km, cs)
        _book(mi, st, cs, stuck, te - t0)
        st[T_S] = s0 + v1 * (te - t0)
        st[T_T] = te
        ist[J_REL] = 0
        _switch(mp, mi, tx, tk, tdk, best_e, st[T_S], y, torque, speed, act, nact, ist, dirs,
                stuck, trial, pw, sc, Sm)
        return 1
    _lti_finish(mp, y, zs, z, tb - t0, km, cs)
    _book(mi, st, cs, stuck, tb - t0)
    st[T_S] = s0 + v1 * (tb - t0)
    st[T_T] = tb
    return 0


@jit_inline
def _stage(meth, stg, y, K, hh, ytmp):
    """ytmp = y + hh sum_j a[stg, j] K[j] (zero couplings skipped: DOP853 has many)."""
    for m in range(N_Y):
        ytmp[m] = 0.0
    for j in range(stg):
        a = _RK_A[meth, stg, j]
        if a != 0.0:
            for m in range(N_Y):
                ytmp[m] += a * K[j, m]
    for m in range(N_Y):
        ytmp[m] = y[m] + hh * ytmp[m]


@jit
def _extend(mp, mi, tx, tk, tdk, meth, t, si, y, ynew, K, R, hh, t0, s0, torque, speed, act,
            nact, sep, dirs, stuck, pw, sc, Sm, ytmp):
    """Continuous extension of the accepted step t -> t + hh into R (DOP853 first evaluates
    its three extra stages); returns its row count for `_interp`."""
    for stg in range(_RK_NS[meth], _RK_NX[meth]):
        _stage(meth, stg, y, K, hh, ytmp)
        _rhs(mp, mi, tx, tk, tdk, t + _RK_C[meth, stg] * hh, si, ytmp, t0, s0, torque, speed,
             act, nact, sep, dirs, stuck, pw, sc, Sm, K[stg])
    return _dense(mi, meth, R, y, ynew, K, hh)


@jit
def _piece(mp, mi, atol, tx, tk, tdk, y, st, ist, dirs, stuck, trial, act, nact, tb, K, R,
           ytmp, ynew, g, gprev, pw, sc, Sm, Lm, Lk, Lv, out):
    """Integrate one contact state from st[T_T] towards tb; stop at the first switch.

    Returns 1 after a switch, 0 on reaching tb, -1 on a step-size failure.
    """
    eps = 2.220446049250313e-16
    t0, s0 = st[T_T], st[T_S]
    torque, speed = st[T_TORQUE], st[T_SPEED]
    v1 = mp[P_RB1] * speed
    sep = ist[J_SEP]  # contact code, held over the piece
    rtol, maxstep, spacing = mp[P_RTOL], mp[P_MAXSTEP], mp[P_SPACING]
    if mi[I_LTI] != 0:  # no friction: only the separation events, set up there
        return _piece_lti(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, trial, act, nact, tb,
                          ytmp, g, gprev, pw, sc, Sm, Lm, Lk, Lv, out)
    meth = mi[I_METHOD]
    ns = _RK_NS[meth]
    expo = -1.0 / _RK_Q[meth]
    ng = _n_events(mi, nact, sep)
    fm = _events_at(mp, mi, tx, tk, tdk, t0, y, t0, s0, torque, speed, act, nact, sep, dirs,
                    stuck, pw, sc, Sm, gprev)
    if fm > out[O_FMAX]:
        out[O_FMAX] = fm
    if fm < out[O_FMIN]:
        out[O_FMIN] = fm
    # A known boundary can invalidate a stick at once (the entering pair takes load, so
    # mu f_mesh drops below the static friction): release it before integrating.
    e0 = _n_sep_events(mi, sep)
    retest = False
    for e in range(e0, ng):
        if stuck[act[e - e0]] != 0 and gprev[e] < 0.0:
            _switch(mp, mi, tx, tk, tdk, e, s0, y, torque, speed, act, nact, ist, dirs, stuck,
                    trial, pw, sc, Sm)
            st[T_REL] = t0
            return 1
        if stuck[act[e - e0]] == 0 and gprev[e] == 0.0 and not (
                ist[J_REL] == act[e - e0] + 1 and st[T_REL] == t0):
            # A slipping pair exactly at v = 0 (a start at rest, standstill): no fall through
            # zero will ever be seen, so apply Eq. (14) now. If it cannot stick it keeps the
            # direction the dynamics carry v to, and integration goes on.
            _switch(mp, mi, tx, tk, tdk, e, s0, y, torque, speed, act, nact, ist, dirs, stuck,
                    trial, pw, sc, Sm)
            if stuck[act[e - e0]] != 0:
                return 1
            retest = True
    if retest:
        _events_at(mp, mi, tx, tk, tdk, t0, y, t0, s0, torque, speed, act, nact, sep, dirs,
                   stuck, pw, sc, Sm, gprev)
    t = t0
    t_knot = t + _next_knot_dt(mp, mi, s0, speed, act, nact)
    h = st[T_H]
    hguess = h if h > 0.0 else 1e-7
    s_idx = s0 + v1 * 0.5 * min(hguess, t_knot - t, tb - t)
    _rhs(mp, mi, tx, tk, tdk, t0, s_idx, y, t0, s0, torque, speed, act, nact, sep, dirs, stuck,
         pw, sc, Sm, K[0])
    R[R_FSTG, 0] = sc[S_KM] * sc[S_COMP]
    if not (h > 0.0):
        h = _initial_step(mp, mi, tx, tk, tdk, t0, y, K[0], s0, torque, speed, act, nact, sep,
                          dirs, stuck, pw, sc, Sm, atol, ytmp, ynew, min(tb, t_knot))
    for m in range(N_Y):  # held components: y's values, which `_interp` leaves in place
        ytmp[m] = y[m]
    while True:
        rejected = False
        while True:  # attempt one step
            hh = min(h, maxstep)
            last = False
            at_knot = False
            lim = tb
            if t_knot < tb:
                lim = t_knot
            if t + 1.0001 * hh >= lim:
                hh = lim - t
                if lim == tb:
                    last = True
                else:
                    at_knot = True
            if hh <= 16.0 * eps * max(abs(t), 1e-300) or not (hh > 0.0):
                if at_knot and hh >= 0.0:  # rounding: the knot is already here
                    t_knot = t + _next_knot_dt(mp, mi, s0 + v1 * (t - t0) + 1e-6 * mp[P_DX]
                                               * (1.0 if speed > 0 else -1.0), speed, act,
                                               nact)
                    continue
                if last and hh >= 0.0:
                    # A boundary a rounding error away from the end of the step (a
                    # communication point on a pair entry): nothing is left to integrate.
                    _book(mi, st, sep, stuck, tb - t0)
                    st[T_S] = s0 + v1 * (tb - t0)
                    st[T_T] = tb
                    return 0
                out[O_TFAIL] = t
                return -1
            si = s0 + v1 * (t + 0.5 * hh - t0)
            tn = lim if (last or at_knot) else t + hh
            for stg in range(1, ns):
                _stage(meth, stg, y, K, hh, ytmp)
                c = _RK_C[meth, stg]
                ts = tn if c == 1.0 else t + c * hh
                _rhs_stage(mp, mi, tx, tk, tdk, ts, si, ytmp, t0, s0, torque, speed, act,
                           nact, sep, dirs, stuck, pw, sc, Sm, K[stg])
                # the mesh force at the stage: its Runge-Kutta quadrature is the force's
                # integral over the step at the method's order (a quadrature component of y,
                # without one: it feeds nothing back and takes no part in the error control)
                R[R_FSTG, stg] = sc[S_KM] * sc[S_COMP]
            for m in range(N_Y):
                ynew[m] = ytmp[m]
            err = _err_norm(mi, meth, y, ynew, K, hh, atol, rtol)
            if not math.isfinite(err):
                err = 1e10
            # Safety factor 0.8, not the usual 0.9: at 0.9 a fifth of all attempts were
            # rejected, most likely because the local error of the lightly damped mesh
            # ringing varies with its phase from step to step. 0.8 halves the rejections,
            # and the error at a given rtol falls by 1.5-2.5 x while the cost stays equal or
            # falls by up to 6 % (interleaved A/B). 0.7 costs more at tight rtol.
            if err <= 1.0:
                fac = 10.0 if err == 0.0 else min(10.0, 0.8 * err ** expo)
                if rejected:
                    fac = min(1.0, fac)
                if (last or at_knot) and hh < h:
                    if fac < 1.0:  # a truncated step keeps the step size it was cut from
                        h = hh * fac
                else:
                    h = hh * fac
                break
            h = hh * max(0.2, 0.8 * err ** expo)
            rejected = True
            out[O_NREJ] += 1.0
        out[O_NSTEPS] += 1.0
        st[T_H] = h
        # scan the step for falls through zero, samples at most `spacing` apart
        nsub = int(math.ceil(hh / spacing * (1.0 - 1e-12)))
        if nsub < 1:
            nsub = 1
        # The continuous extension is needed only to sample inside the step. DOP853's costs
        # three more stages, so its samples are first taken on the cubic Hermite of the step
        # ends; a fall seen there is re-scanned on the full extension (the end values are
        # exact either way, so a single crossing is always caught).
        nf = 0
        cheap = False
        fm_end = 0.0
        if nsub > 1:
            # the last stage was evaluated at the step end: keep its event values
            _event_values(mp, mi, nact, sep, act, dirs, pw, sc, g)
            fm_end = sc[S_KM] * sc[S_COMP]
            for e in range(ng):
                R[R_GEND, e] = g[e]
            if _RK_NX[meth] > ns:
                nf = _hermite(R, y, ynew, K, hh, ns - 1)
                cheap = True
                for e in range(ng):
                    R[R_GSAVE, e] = gprev[e]
            else:
                nf = _extend(mp, mi, tx, tk, tdk, meth, t, si, y, ynew, K, R, hh, t0, s0,
                             torque, speed, act, nact, sep, dirs, stuck, pw, sc, Sm, ytmp)
        while True:
            hit = False
            th_prev = 0.0
            th_hit = 1.0
            for ks in range(1, nsub + 1):
                if ks == nsub:
                    th = 1.0
                    if nsub == 1:
                        _event_values(mp, mi, nact, sep, act, dirs, pw, sc, g)
                        fm = sc[S_KM] * sc[S_COMP]
                    else:
                        for e in range(ng):
                            g[e] = R[R_GEND, e]
                        fm = fm_end
                else:
                    th = ks / nsub
                    _interp(mi, R, nf, th, ytmp)
                    fm = _events_light(mp, mi, tx, tk, tdk, t + th * hh, ytmp, t0, s0,
                                       torque, speed, act, nact, sep, dirs, stuck, pw, sc,
                                       Sm, g)
                if fm > out[O_FMAX]:
                    out[O_FMAX] = fm
                if fm < out[O_FMIN]:
                    out[O_FMIN] = fm
                for e in range(ng):
                    if gprev[e] > 0.0 and g[e] <= 0.0:
                        hit = True
                        break
                if hit:
                    th_hit = th
                    break
                for e in range(ng):
                    gprev[e] = g[e]
                th_prev = th
            if not (hit and cheap):
                break
            nf = _extend(mp, mi, tx, tk, tdk, meth, t, si, y, ynew, K, R, hh, t0, s0, torque,
                         speed, act, nact, sep, dirs, stuck, pw, sc, Sm, ytmp)
            cheap = False
            for e in range(ng):
                gprev[e] = R[R_GSAVE, e]
        if hit:
            if nsub == 1:
                nf = _extend(mp, mi, tx, tk, tdk, meth, t, si, y, ynew, K, R, hh, t0, s0,
                             torque, speed, act, nact, sep, dirs, stuck, pw, sc, Sm, ytmp)
            # Refine every falling function on the interpolant (Illinois); keep the earliest.
            best_th = th_hit
            best_e = -1
            tol_th = (mp[P_TTOL] + 8.0 * eps * abs(t)) / hh
            for e in range(ng):
                if not (gprev[e] > 0.0 and g[e] <= 0.0):
                    continue
                a, ga = th_prev, gprev[e]
                b, gb = th_hit, g[e]
                side = 0
                for _it in range(200):
                    if b - a <= tol_th:
                        break
                    c = _illinois_point(a, ga, b, gb)
                    _interp(mi, R, nf, c, ytmp)
                    _events_at(mp, mi, tx, tk, tdk, t + c * hh, ytmp, t0, s0, torque, speed,
                               act, nact, sep, dirs, stuck, pw, sc, Sm, ynew)
                    a, ga, b, gb, side = _illinois(a, ga, b, gb, c, ynew[e], side)
                if best_e < 0 or b < best_th:
                    best_th, best_e = b, e
            te = t + best_th * hh
            if best_th >= 1.0:
                te = tn
            # the force's integral up to the switch: Gauss-Legendre on the continuous
            # extension (the stage quadrature covers whole steps only)
            fi = 0.0
            for gi in range(3):
                _interp(mi, R, nf, _GL3_X[gi] * best_th, ytmp)
                fi += _GL3_W[gi] * _events_at(mp, mi, tx, tk, tdk,
                                              t + _GL3_X[gi] * best_th * hh, ytmp, t0, s0,
                                              torque, speed, act, nact, sep, dirs, stuck, pw,
                                              sc, Sm, ynew)
            out[O_FINT] += fi * (te - t)
            _interp(mi, R, nf, best_th, ytmp)
            for m in range(N_Y):
                y[m] = ytmp[m]
            _book(mi, st, sep, stuck, te - t0)
            st[T_S] = s0 + v1 * (te - t0)
            st[T_T] = te
            ist[J_REL] = 0
            _switch(mp, mi, tx, tk, tdk, best_e, st[T_S], y, torque, speed, act, nact, ist,
                    dirs, stuck, trial, pw, sc, Sm)
            if ist[J_REL] != 0:
                st[T_REL] = te
            return 1
        fi = 0.0
        for j in range(ns - 1):  # the weights b: the last row of A (first same as last)
            fi += _RK_A[meth, ns - 1, j] * R[R_FSTG, j]
        out[O_FINT] += hh * fi
        R[R_FSTG, 0] = R[R_FSTG, ns - 1]
        for m in range(N_Y):
            y[m] = ynew[m]
            K[0, m] = K[ns - 1, m]
        t = tn
        if last:
            _book(mi, st, sep, stuck, tb - t0)
            st[T_S] = s0 + v1 * (tb - t0)
            st[T_T] = tb
            return 0
        if at_knot:
            t_knot = t + _next_knot_dt(mp, mi, s0 + v1 * (t - t0), speed, act, nact)
            if mi[I_KIND] == KIND_TABLE:
                # next table interval: the parametric power changes its slope there (a
                # spline's slope is continuous at its knots)
                si = s0 + v1 * (t + 0.5 * min(h, t_knot - t, tb - t) - t0)
                K[0, 15] = _param_rate(mp, mi, tdk, si, y, act, nact, sep, speed)

@jit_inline
def _any_stuck(mi, stuck):
    for j in range(mi[I_NP]):
        if stuck[j] != 0:
            return True
    return False


@jit_inline  # single caller (`_advance`)
def _segment(mp, mi, atol, tx, tk, tdk, y, st, ist, dirs, stuck, trial, prev_act, act, tb,
             K, R, ytmp, ynew, g, gprev, pw, sc, Sm, Lm, Lk, Lv, out):
    """One segment between known boundaries (ReferenceEngine.advance's loop body)."""
    speed, torque = st[T_SPEED], st[T_TORQUE]
    rb1 = mp[P_RB1]
    npairs = mi[I_NP]
    s_mid = st[T_S] + rb1 * speed * (0.5 * (st[T_T] + tb) - st[T_T])
    nudge = 1e-9 * mp[P_PB]
    if abs(s_mid - st[T_S]) < nudge and speed != 0.0:
        # a (near) zero-length segment sits on a boundary: take the set after it, so a step
        # ending on a pair entry reports the new set whichever side rounding put it
        s_mid = st[T_S] + (nudge if speed > 0.0 else -nudge)
    nact = _active_at(mp, mi, s_mid, act)
    nprev = ist[J_NPREV]
    if nprev >= 0:  # pairs that left contact are no longer stuck
        for j in range(npairs):
            inside = False
            for i in range(nact):
                if act[i] == j:
                    inside = True
            if not inside:
                stuck[j] = 0
    _settle(mp, mi, st[T_S], y, speed, act, nact, ist[J_SEP], dirs, stuck)
    if nprev >= 0 and mi[I_KIND] != KIND_CONSTANT:
        # Stored mesh energy jumps when a pair enters or leaves: book it as parametric (the
        # constant law keeps its total whichever pairs are in mesh).
        km_before = 0.0
        for i in range(nprev):
            xi = _pair_xi(mp, st[T_S], prev_act[i])
            km_before += _pair_k(mp, mi, tx, tk, tdk, xi, xi, nprev)
        _evaluate(mp, mi, tx, tk, tdk, st[T_S], st[T_S], y, torque, speed, act, nact,
                  ist[J_SEP], dirs, stuck, pw, sc, Sm)
        y[15] += 0.5 * (sc[S_KM] - km_before) * sc[S_COMP] ** 2
    while st[T_T] < tb:
        r = _piece(mp, mi, atol, tx, tk, tdk, y, st, ist, dirs, stuck, trial, act, nact, tb,
                   K, R, ytmp, ynew, g, gprev, pw, sc, Sm, Lm, Lk, Lv, out)
        if r < 0:
            out[O_STATUS] = STATUS_STEP
            return
        out[O_NEV] += r
        if out[O_NEV] > mi[I_MAXEV]:
            out[O_STATUS] = STATUS_EVENTS
            out[O_TFAIL] = st[T_T]
            return
    for i in range(nact):
        prev_act[i] = act[i]
    ist[J_NPREV] = nact


@jit_inline
def _kinetic(mp, y):
    """Kinetic energy 0.5 q'^T M q' (J)."""
    e = 0.0
    for m in range(6):
        if mp[P_MINV + m] > 0.0:
            e += 0.5 * y[6 + m] * y[6 + m] / mp[P_MINV + m]
    return e


@jit_inline
def _current_active(mp, mi, st, ist, prev_act, act):
    """The pairs of the last segment (a state on a boundary keeps its set), else the set at
    the current mesh travel; returns their number."""
    if ist[J_NPREV] >= 0:
        for i in range(ist[J_NPREV]):
            act[i] = prev_act[i]
        return ist[J_NPREV]
    return _active_at(mp, mi, st[T_S], act)


@jit
def _speed_change(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, prev_act, act, torque, speed,
                  h, pw, sc, Sm):
    """`switching.speed_change`: stuck pairs after a jump of the speed input."""
    if mi[I_FRIC] != FR_STICK or ist[J_SEP] != 0:
        return
    nact = _current_active(mp, mi, st, ist, prev_act, act)
    full = mi[I_SLIDE] == 1
    tr = 0.0 if mi[I_TORS] != 0 else 1.0
    for i in range(nact):
        j = act[i]
        if stuck[j] == 0:
            continue
        stuck[j] = 0  # evaluate as slipping: only v and the normal force are needed
        _evaluate(mp, mi, tx, tk, tdk, st[T_S], st[T_S], y, torque, speed, act, nact, 0, dirs,
                  stuck, pw, sc, Sm)
        stuck[j] = 1
        v = pw[W_V, i]
        if v == 0.0:
            continue
        w2, w5 = pw[W_S1M, i] * mp[P_IRB1], pw[W_S2M, i] * mp[P_IRB2]
        # impulse along w = [-1, 0, w2, 1, 0, w5] changes v by S lambda
        if full:
            S = -(tr * (mp[P_MINV] + mp[P_MINV + 3]) + mp[P_MINV + 2] * w2 * w2
                  + mp[P_MINV + 5] * w5 * w5)
        else:
            S = -(mp[P_MINV] + mp[P_MINV + 3])
        if abs(v) <= mp[P_MU] * abs(pw[W_N, i]) * h * abs(S):
            lam = -v / S
            ke0 = _kinetic(mp, y)
            y[6] -= tr * mp[P_MINV] * lam
            y[8] += mp[P_MINV + 2] * w2 * lam
            y[9] += tr * mp[P_MINV + 3] * lam
            y[11] += mp[P_MINV + 5] * w5 * lam
            y[14] += _kinetic(mp, y) - ke0  # the impulse is friction work
        else:
            stuck[j] = 0
            dirs[j] = _sgn(v, 1.0)
    _settle(mp, mi, st[T_S], y, speed, act, nact, 0, dirs, stuck)


@jit
def _advance(mp, mi, atol, tx, tk, tdk, y, st, ist, dirs, stuck, trial, prev_act, act, t_end,
             torque, speed, offs, kcur, K, R, ytmp, ynew, g, gprev, pw, sc, Sm, Lm, Lk, Lv,
             out):
    """ReferenceEngine.advance: segments between the known boundaries, then t_end."""
    for i in range(N_OUT):
        out[i] = 0.0
    out[O_FMAX] = -np.inf
    out[O_FMIN] = np.inf
    if speed != st[T_SPEED]:
        _speed_change(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, prev_act, act, torque,
                      speed, t_end - st[T_T], pw, sc, Sm)
    st[T_TORQUE] = torque
    st[T_SPEED] = speed
    t_start, s_start = st[T_T], st[T_S]
    v1 = mp[P_RB1] * speed
    pb = mp[P_PB]
    noff = 3 if mi[I_FRIC] == FR_NOMINAL else 2
    if mi[I_LTI] != 0 and mi[I_KIND] == KIND_CONSTANT:
        noff = 0  # no friction and the same total stiffness whichever pairs are in mesh
    offs[0] = 0.0
    offs[1] = np.fmod(mp[P_L], pb)
    offs[2] = np.fmod(mp[P_XIP], pb)
    s_end = s_start + v1 * (t_end - t_start)
    fwd = speed > 0.0
    # boundaries a rounding error past the end of the step count as inside it (see _segment)
    s_tol = abs(v1) * 16.0 * 2.220446049250313e-16 * max(1.0, abs(t_end))
    s_lim = s_end + s_tol if fwd else s_end - s_tol
    if speed != 0.0:
        for i in range(noff):
            if fwd:
                k = math.floor((s_start - offs[i]) / pb)
                while k * pb + offs[i] <= s_start:
                    k += 1
            else:
                k = math.ceil((s_start - offs[i]) / pb)
                while k * pb + offs[i] >= s_start:
                    k -= 1
            kcur[i] = k
    last_b = np.nan
    while True:
        tb = t_end
        if speed != 0.0:
            ib = -1
            bb = 0.0
            for i in range(noff):
                b = kcur[i] * pb + offs[i]
                if ib < 0 or (fwd and b < bb) or ((not fwd) and b > bb):
                    ib, bb = i, b
            if (fwd and bb < s_lim) or ((not fwd) and bb > s_lim):
                kcur[ib] += 1 if fwd else -1
                if bb == last_b:
                    continue
                last_b = bb
                tb = t_start + (bb - s_start) / v1
                tb = min(max(tb, st[T_T]), t_end)
            else:
                ib = -1
            if ib < 0:
                tb = t_end
        else:
            ib = -1
        _segment(mp, mi, atol, tx, tk, tdk, y, st, ist, dirs, stuck, trial, prev_act, act, tb,
                 K, R, ytmp, ynew, g, gprev, pw, sc, Sm, Lm, Lk, Lv, out)
        if out[O_STATUS] != STATUS_OK:
            return
        if ib < 0:
            break
    st[T_T] = t_end
    ist[J_NEVTOT] += int(out[O_NEV])


@jit
def _eval_now(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, prev_act, act, pw, sc, Sm):
    """Evaluate at the current state (active set of the last segment); returns nact."""
    nact = _current_active(mp, mi, st, ist, prev_act, act)
    _evaluate(mp, mi, tx, tk, tdk, st[T_S], st[T_S], y, st[T_TORQUE], st[T_SPEED], act, nact,
              ist[J_SEP], dirs, stuck, pw, sc, Sm)
    return nact


N_O = 10  # outputs: dte, mesh, friction, state, out torque, reaction, in torque, w1, w2, v


@jit
def _outputs_now(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, prev_act, act, pw, sc, Sm, o):
    """`Outputs` at the current state into ``o`` (compiled: the FMU reads them every step)."""
    nact = _eval_now(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, prev_act, act, pw, sc, Sm)
    rb1, rb2 = mp[P_RB1], mp[P_RB2]
    mesh = sc[S_KM] * sc[S_COMP]
    cs = ist[J_SEP]
    state = CONTACT_SLIP
    if cs == 2:
        state = CONTACT_BACK
    elif cs == 1:
        state = CONTACT_SEPARATED
    else:
        for i in range(nact):
            if stuck[act[i]] != 0:
                state = CONTACT_STICK
    fr = 0.0
    fm = 0.0
    i_near = 0
    best = np.inf
    for i in range(nact):
        fr += pw[W_F, i]
        fm += pw[W_F, i] * pw[W_S1M, i]
        d = abs(pw[W_XI, i] - mp[P_XIP])
        if d < best:
            best, i_near = d, i
    damp = sc[S_THETA] * mp[P_CM] * sc[S_DDELTA]
    speed = st[T_SPEED]
    o[0] = sc[S_DELTA]
    o[1] = mesh
    o[2] = fr
    o[3] = state
    o[4] = -rb2 * (mp[P_KB + 5] * (y[5] - y[Y_A]) + mp[P_C + 5] * (y[11] - y[Y_AD]))
    o[5] = rb1 * (mesh + damp) - fm
    o[6] = st[T_TORQUE] - rb1 * (mp[P_KB + 2] * y[2] + mp[P_C + 2] * y[8])
    o[7] = speed + y[8] / rb1
    o[8] = speed * mp[P_RATIO] - y[11] / rb2
    o[9] = pw[W_V, i_near] if nact > 0 else 0.0


# a recorded row: outputs, stick and separation fractions, peak force, events, back-flank
# fraction, mean and least mesh force over the interval
N_REC = N_O + 7


@jit
def _run_grid(mp, mi, atol, tx, tk, tdk, y, st, ist, dirs, stuck, trial, prev_act, act, grid,
              torque, speed, yad, offs, kcur, K, R, ytmp, ynew, g, gprev, pw, sc, Sm, Lm, Lk,
              Lv, out, o, rec):
    """`advance` to every point of ``grid`` (inputs of interval i held from grid[i]) and
    record the outputs and step figures there, without a return to Python per point.

    Returns the number of rows filled; fewer than ``len(grid)`` means the step into the next
    row failed (``out`` holds why).
    """
    n = grid.shape[0]
    _outputs_now(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, prev_act, act, pw, sc, Sm, o)
    for m in range(N_O):
        rec[m, 0] = o[m]
    rec[N_O + 2, 0] = o[1]
    rec[N_O + 5, 0] = o[1]
    rec[N_O + 6, 0] = o[1]
    for i in range(1, n):
        t0, stick0, sep0, back0 = st[T_T], st[T_STICK], st[T_SEP], st[T_BACK]
        y[Y_AD] = yad[i - 1]
        _advance(mp, mi, atol, tx, tk, tdk, y, st, ist, dirs, stuck, trial, prev_act, act,
                 grid[i], torque[i - 1], speed[i - 1], offs, kcur, K, R, ytmp, ynew, g, gprev,
                 pw, sc, Sm, Lm, Lk, Lv, out)
        if out[O_STATUS] != STATUS_OK:
            return i
        _outputs_now(mp, mi, tx, tk, tdk, y, st, ist, dirs, stuck, prev_act, act, pw, sc, Sm,
                     o)
        h = grid[i] - t0
        for m in range(N_O):
            rec[m, i] = o[m]
        rec[N_O, i] = (st[T_STICK] - stick0) / h
        rec[N_O + 1, i] = (st[T_SEP] - sep0) / h
        rec[N_O + 2, i] = max(out[O_FMAX], o[1])
        rec[N_O + 3, i] = out[O_NEV]
        rec[N_O + 4, i] = (st[T_BACK] - back0) / h
        rec[N_O + 5, i] = out[O_FINT] / h
        rec[N_O + 6, i] = min(out[O_FMIN], o[1])
    return n


@jit
def _reset_settle(mp, mi, y, st, ist, dirs, stuck, act):
    nact = _active_at(mp, mi, st[T_S], act)
    _settle(mp, mi, st[T_S], y, st[T_SPEED], act, nact, ist[J_SEP], dirs, stuck)


# -- the engine -----------------------------------------------------------------------------
class FastEngine(Engine):
    """numba engine implementing the `Engine` contract with the reference's physics.

    Parameters
    ----------
    params, effects : the gear pair and the effects to include
    rtol : relative tolerance of the Runge-Kutta error control
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
        ``expm(A h)`` (`_piece_lti`) instead of Runge-Kutta. False keeps Runge-Kutta
        (for comparison).
    method : ``"dop853"`` (default) or ``"dp5"``, the Runge-Kutta pair (see the module
        docstring); ``gearpair bench`` compares the two
    """

    def __init__(self, params: GearParams | None = None, effects: Effects | None = None,
                 rtol: float = 1e-8, atol: float | None = None, max_step: float | None = None,
                 n_samples: int = 8, sample_spacing: float | None = None, t_tol: float = 1e-14,
                 max_events: int = 100_000, exact_lti: bool = True,
                 method: str = "dop853") -> None:
        if method not in _METHOD_CODE:
            raise ValueError(f"method = {method!r} is not known; allowed "
                             f"{', '.join(sorted(_METHOD_CODE))}")
        check_rtol(rtol)
        if not (1 <= int(n_samples) <= 1000):
            raise ValueError(f"n_samples = {n_samples!r} is out of range; allowed [1, 1000]")
        m = self.model = Model.build(params, effects)
        fx, st = m.effects, m.stiff
        if m.mu_static != m.mu or fx.stribeck_velocity is not None:
            raise ValueError("mu_static (other than mu) and stribeck_velocity are not in the "
                             "fast engine yet; use engine=\"reference\" (FMU: engine = 1)")
        self.rtol = float(rtol)
        self.atol = _SCALE * rtol if atol is None else np.full(N_Y, float(atol))
        if max_step is None:
            from .modal import natural_frequencies

            max_step = 0.5 / float(natural_frequencies(m, "slip")[-1])
        self.max_step = float(max_step)
        n = m.geom.n_pairs
        mp = np.zeros(N_MP)
        mp[P_MINV:P_MINV + 6] = m.minv
        mp[P_C:P_C + 6] = m.c_diag
        mp[P_KB:P_KB + 6] = m.kb_diag
        g = m.geom
        mp[P_RB1], mp[P_RB2], mp[P_RATIO], mp[P_CM], mp[P_MU] = m.rb1, m.rb2, m.ratio, m.cm, m.mu
        mp[P_VEPS] = fx.v_eps
        mp[P_S1A], mp[P_S1S2], mp[P_PB] = g.s1a, g.s1s2, g.base_pitch
        mp[P_L], mp[P_PER], mp[P_XIP] = g.path_length, g.period_length, g.xi_pitch
        mp[P_KMEAN] = st.km_mean
        mp[P_IRB1], mp[P_IRB2], mp[P_IPER] = 1.0 / m.rb1, 1.0 / m.rb2, 1.0 / g.period_length
        mp[P_RTOL], mp[P_MAXSTEP], mp[P_TTOL] = self.rtol, self.max_step, float(t_tol)
        self.sample_spacing = float(self.max_step / (n_samples + 1) if sample_spacing is None
                                    else sample_spacing)
        mp[P_SPACING] = self.sample_spacing
        mi = np.zeros(N_MI, dtype=np.int64)
        mi[I_NP] = n
        mi[I_KIND] = KIND_CONSTANT if st.kind == "constant" else \
            KIND_CUBIC if st.cubic is not None else KIND_TABLE
        mi[I_VARY] = 0 if st.kind in ("constant", "rectangular") else 1
        mi[I_SEP] = 1 if fx.separation else 0
        mi[I_FRIC] = _FRICTION_CODE[fx.friction]
        mi[I_SLIDE] = 1 if fx.sliding == "full" else 0
        mi[I_TIE] = 1 if fx.stick_tie == "paper" else 0
        mi[I_NSAMP] = int(n_samples)
        mi[I_MAXEV] = int(max_events)
        mi[I_BACK] = 1 if fx.backlash is not None else 0
        mp[P_BACK] = 0.0 if fx.backlash is None else float(fx.backlash)
        mi[I_TORS] = 1 if m.torsional else 0
        # constant coefficients between switches: the exact propagator replaces Runge-Kutta
        mi[I_LTI] = 1 if (fx.friction == "off" and st.kind in ("constant", "rectangular")
                          and exact_lti) else 0
        mi[I_METHOD] = _METHOD_CODE[method]
        ix = integrated_components(bool(m.torsional), fx.friction != "off", bool(mi[I_VARY]))
        mi[I_NIX] = len(ix)
        mi[I_IX:I_IX + len(ix)] = ix
        self.integrated = ix  # components of y the Runge-Kutta steps integrate
        self._held_q = np.setdiff1d(np.arange(2 * N_Q), ix)  # q, q' that stay at rest
        self.method = method
        self._mp, self._mi = mp, mi
        self._tx = np.ascontiguousarray(st.xi, dtype=float)
        if st.cubic is not None:  # 4 coefficients per interval; tdk: the slope at its start
            self._tk = np.ascontiguousarray(st.cubic, dtype=float).ravel()
            self._tdk = np.ascontiguousarray(st.cubic[:, 1], dtype=float)
        else:
            self._tk = np.ascontiguousarray(st.k, dtype=float)
            self._tdk = np.diff(self._tk) / np.diff(self._tx)
        ntab = len(self._tx)
        mi[I_NTAB] = ntab
        mp[P_DX] = g.path_length / (ntab - 1)
        mp[P_INVDX] = 1.0 / mp[P_DX]
        if np.max(np.abs(self._tx - mp[P_DX] * np.arange(ntab))) > 1e-9 * mp[P_DX]:
            raise ValueError("FastEngine needs the stiffness table on a uniform grid from 0 "
                             "to the path length (MeshStiffness.build makes one)")
        # state: views into one buffer, so a rollback snapshot is one copy (the FMU takes one
        # every doStep); the integer parts are int64 views of float64 words
        cut = np.cumsum([0, N_Y, N_ST, N_IST, n, n, n])
        self._state = np.zeros(int(cut[-1]))
        part = [self._state[cut[i]:cut[i + 1]] for i in range(6)]
        self._y, self._st, self._dirs = part[0], part[1], part[3]
        self._ist, self._stuck, self._prev = (part[i].view(np.int64) for i in (2, 4, 5))
        self._last = None
        # work arrays (allocated once)
        self._trial = np.zeros(n, dtype=np.int64)
        self._act = np.zeros(n, dtype=np.int64)
        self._offs = np.zeros(3)
        self._kcur = np.zeros(3, dtype=np.int64)
        self._K = np.zeros((RK_NK, N_Y))
        self._R = np.zeros((R_FSTG + 1, max(N_Y, n + 2, RK_NK)))
        self._ytmp = np.zeros(N_Y)
        self._ynew = np.zeros(N_Y)
        self._g = np.zeros(n + 2)
        self._gprev = np.zeros(n + 2)
        self._pw = np.zeros((N_PW, n))
        self._sc = np.zeros(N_SC)
        self._Sm = np.zeros((n, n + 2))
        self._out = np.zeros(N_OUT)
        self._Lm = np.zeros((L_SCRATCH + 12, NZ, NZ))
        self._Lk = np.zeros((L_NSLOT + 1, 4))
        self._Lk[:L_NSLOT, 0] = -1.0  # empty slots
        self._Lv = np.zeros((6, max(NZ, N_Y)))
        self._o = np.zeros(N_O)
        self._outputs: Outputs | None = None  # cache, valid until the state changes
        self._o_fresh = False  # self._o holds the outputs of the current state
        self.reset()

    # -- contract ----------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return float(self._st[T_T])

    def reset(self, t0: float = 0.0, torque: float = 0.0, speed: float = 0.0,
              static: bool = True) -> None:
        check_inputs(torque, speed)
        m = self.model
        self._st[:] = 0.0
        self._st[T_T] = float(t0)
        self._st[T_TORQUE], self._st[T_SPEED] = float(torque), float(speed)
        self._y[:] = 0.0
        active, _, _, _, k = m.contact(0.0)
        if static and torque != 0.0:
            self._y[:N_Q] = m.static_deflection(torque, float(k.sum()))
        self._prev[:len(active)] = active  # the set in contact at t0 (as the reference)
        delta = self._y[1] - self._y[4] + self._y[2] + self._y[5]
        self._ist[:] = 0
        self._ist[J_SEP] = m.contact_code(delta)
        self._ist[J_NPREV] = len(active)
        self._dirs[:] = 1.0
        self._stuck[:] = 0
        _reset_settle(self._mp, self._mi, self._y, self._st, self._ist, self._dirs, self._stuck,
                      self._act)
        self._last = None
        self._stale()

    def get_state(self) -> dict:
        npv = int(self._ist[J_NPREV])
        return {
            "t": float(self._st[T_T]), "s": float(self._st[T_S]), "y": self._y.copy(),
            "torque": float(self._st[T_TORQUE]), "speed": float(self._st[T_SPEED]),
            "separated": bool(self._ist[J_SEP]), "back": bool(self._ist[J_SEP] == 2),
            "dirs": self._dirs.copy(),
            "stuck": self._stuck.astype(bool), "t_stick": float(self._st[T_STICK]),
            "t_sep": float(self._st[T_SEP]), "t_back": float(self._st[T_BACK]),
            "n_events_total": int(self._ist[J_NEVTOT]),
            "h": float(self._st[T_H]) if self._st[T_H] > 0 else None,
            "prev_active": None if npv < 0 else [int(j) for j in self._prev[:npv]],
            "last": self._last,
        }

    def set_state(self, state: dict) -> None:
        y = np.asarray(state["y"], dtype=float)
        moving = [int(i) for i in self._held_q if y[i] != 0.0]
        if moving:
            raise ValueError(
                f"state: y[{moving[0]}] = {y[moving[0]]!r}, but with these effects "
                f"components {[int(i) for i in self._held_q]} of y (x1, y1, x2, y2 at "
                "indices 0, 1, 3, 4 and their rates 6 + i) are not simulated and must be 0")
        self._st[T_T], self._st[T_S] = float(state["t"]), float(state["s"])
        self._y[:] = y
        self._st[T_TORQUE], self._st[T_SPEED] = float(state["torque"]), float(state["speed"])
        self._ist[J_SEP] = (2 if state.get("back") else 1) if state["separated"] else 0
        self._dirs[:] = np.asarray(state["dirs"], dtype=float)
        self._stuck[:] = np.asarray(state["stuck"], dtype=bool).astype(np.int64)
        self._st[T_STICK], self._st[T_SEP] = float(state["t_stick"]), float(state["t_sep"])
        self._st[T_BACK] = float(state.get("t_back", 0.0))
        self._ist[J_NEVTOT] = int(state["n_events_total"])
        h = state.get("h")
        self._st[T_H] = float(h) if h else 0.0
        prev = state.get("prev_active")
        if prev is None:
            self._ist[J_NPREV] = -1
        else:
            self._ist[J_NPREV] = len(prev)
            self._prev[:len(prev)] = np.asarray(prev, dtype=np.int64)
        self._last = state.get("last")
        self._stale()

    def _stale(self) -> None:
        """The state changed: both output caches (`output_values`, `outputs`) are stale."""
        self._outputs = None
        self._o_fresh = False

    def snapshot(self) -> tuple:
        """A cheap copy of the whole state for a rollback within this process (`restore`);
        `get_state` is the portable, picklable form."""
        return self._state.copy(), self._last

    def restore(self, snap: tuple) -> None:
        """Return to a `snapshot` of this engine."""
        self._state[:], self._last = snap
        self._stale()

    def advance(self, t_end: float, torque: float, speed: float,
                load_speed: float | None = None) -> StepSummary:
        check_inputs(torque, speed, load_speed)
        t_start = self.time
        f = self.advance_values(t_end, torque, speed, load_speed)
        return StepSummary(t_start, float(t_end), *f)

    def advance_values(self, t_end: float, torque: float, speed: float,
                       load_speed: float | None = None) -> tuple:
        """`advance` for a caller that has validated the inputs and reads plain numbers (the
        FMU's doStep, where each microsecond counts): no input check, no dataclass.

        Returns
        -------
        (stick_fraction, separation_fraction, mesh_force_max, n_events, n_steps,
        back_fraction, mesh_force_mean, mesh_force_min) of the step (`StepSummary`'s order);
        `output_values` then has the outputs.
        """
        t_start = self.time
        if not (t_end > t_start):
            raise ValueError(f"t_end = {t_end!r} must be after the current time {t_start!r}")
        t_stick0, t_sep0, t_back0 = self._st[T_STICK], self._st[T_SEP], self._st[T_BACK]
        mp = self._mp
        self._y[Y_AD] = 0.0 if load_speed is None else \
            -mp[P_RB2] * (float(load_speed) - float(speed) * mp[P_RATIO])
        out = self._out
        self._stale()
        _advance(self._mp, self._mi, self.atol, self._tx, self._tk, self._tdk, self._y,
                 self._st, self._ist, self._dirs, self._stuck, self._trial, self._prev,
                 self._act, float(t_end), float(torque), float(speed), self._offs, self._kcur,
                 self._K, self._R, self._ytmp, self._ynew, self._g, self._gprev, self._pw,
                 self._sc, self._Sm, self._Lm, self._Lk, self._Lv, out)
        self._raise_failure()
        h = t_end - t_start
        o = self.output_values()
        self._last = (t_start, float(t_end))
        return ((self._st[T_STICK] - t_stick0) / h, (self._st[T_SEP] - t_sep0) / h,
                max(float(out[O_FMAX]), float(o[1])), int(out[O_NEV]), int(out[O_NSTEPS]),
                (self._st[T_BACK] - t_back0) / h, float(out[O_FINT]) / h,
                min(float(out[O_FMIN]), float(o[1])))

    def _raise_failure(self) -> None:
        out = self._out
        status = int(out[O_STATUS])
        if status == STATUS_EVENTS:
            raise RuntimeError(
                f"more than {int(self._mi[I_MAXEV])} contact switches in one step "
                f"(t = {out[O_TFAIL]:.9g} s): the run stalls; see README 'Limits'")
        if status == STATUS_STEP:
            raise ArithmeticError(
                f"Runge-Kutta step size underflow at t = {out[O_TFAIL]:.9g} s")

    def run_grid(self, grid, torque, speed, load_speed=None) -> dict:
        """Step through ``grid`` (s, from the current time) in one compiled call and record
        at every point: what `results.simulate` gets from `advance` + `outputs` per point,
        without the Python round trip (about 20 us) per point.

        Parameters
        ----------
        grid : increasing times (s); ``grid[0]`` is the current time
        torque, speed, load_speed : N.m, rad/s, rad/s per interval (``len(grid) - 1``
            values, held from ``grid[i]`` to ``grid[i + 1]``); ``load_speed`` None as in
            `advance`

        Returns
        -------
        dict of arrays over ``grid``: the `Outputs` fields and the `StepSummary` figures
        ``stick_fraction``, ``separation_fraction``, ``back_fraction``, ``mesh_force_mean``,
        ``mesh_force_min``, ``mesh_force_max``, ``n_events`` of the interval ending there
        (row 0: the start).
        """
        grid = np.ascontiguousarray(grid, dtype=float)
        n = len(grid)
        if n < 1 or abs(grid[0] - self.time) > 1e-12 * max(1.0, abs(self.time)):
            raise ValueError(f"grid must start at the current time {self.time!r}")
        if n > 1 and not np.all(np.diff(grid) > 0):
            raise ValueError("grid must increase strictly")
        T = np.ascontiguousarray(np.broadcast_to(np.asarray(torque, float), (n - 1,)))
        W = np.ascontiguousarray(np.broadcast_to(np.asarray(speed, float), (n - 1,)))
        L = None if load_speed is None else np.broadcast_to(np.asarray(load_speed, float),
                                                            (n - 1,))
        ok = np.isfinite(T) & np.isfinite(W) & (np.abs(T) <= 1e6) & (np.abs(W) <= 2e4)
        if L is not None:
            ok &= np.isfinite(L) & (np.abs(L) <= 2e4)
        if not np.all(ok):  # the same message as advance, for the first bad interval
            i = int(np.argmin(ok))
            check_inputs(T[i], W[i], None if L is None else L[i])
        mp = self._mp
        yad = np.zeros(n - 1) if L is None else \
            np.ascontiguousarray(-mp[P_RB2] * (L - W * mp[P_RATIO]))
        rec = np.zeros((N_REC, n))  # one contiguous row per signal: returned without a copy
        self._stale()
        filled = _run_grid(self._mp, self._mi, self.atol, self._tx, self._tk, self._tdk,
                           self._y, self._st, self._ist, self._dirs, self._stuck, self._trial,
                           self._prev, self._act, grid, T, W, yad, self._offs, self._kcur,
                           self._K, self._R, self._ytmp, self._ynew, self._g, self._gprev,
                           self._pw, self._sc, self._Sm, self._Lm, self._Lk, self._Lv,
                           self._out, self._o, rec)
        if filled > 1:
            self._last = (float(grid[filled - 2]), float(grid[filled - 1]))
        if filled < n:
            self._raise_failure()
        names = [f.name for f in fields(Outputs)][1:]  # time first, then the N_O values
        data = {k: rec[m] for m, k in enumerate(names)}
        data["contact_state"] = data["contact_state"].astype(int)
        for m, k in enumerate(("stick_fraction", "separation_fraction", "mesh_force_max",
                               "n_events", "back_fraction", "mesh_force_mean",
                               "mesh_force_min")):
            data[k] = rec[N_O + m]
        return data

    # -- outputs -----------------------------------------------------------------------------
    def _now(self) -> int:
        return int(_eval_now(self._mp, self._mi, self._tx, self._tk, self._tdk, self._y,
                             self._st, self._ist, self._dirs, self._stuck, self._prev,
                             self._act, self._pw, self._sc, self._Sm))

    def output_values(self) -> np.ndarray:
        """The `Outputs` values after ``time``, in field order, as the engine's own array
        (read it before the next step; `outputs` is the dataclass)."""
        if not self._o_fresh:
            _outputs_now(self._mp, self._mi, self._tx, self._tk, self._tdk, self._y, self._st,
                         self._ist, self._dirs, self._stuck, self._prev, self._act, self._pw,
                         self._sc, self._Sm, self._o)
            self._o_fresh = True
        return self._o

    def outputs(self) -> Outputs:
        if self._outputs is None:
            o = self.output_values()
            self._outputs = Outputs(float(self._st[T_T]), float(o[0]), float(o[1]),
                                    float(o[2]), int(o[3]), float(o[4]), float(o[5]),
                                    float(o[6]), float(o[7]), float(o[8]), float(o[9]))
        return self._outputs

    def energy(self) -> dict:
        """Stored energy and the integrated power terms so far (J), as the reference."""
        m = self.model
        self._now()
        sc, y = self._sc, self._y
        q, qd = y[:N_Q], y[N_Q:2 * N_Q]
        stored = 0.5 * qd @ m.M @ qd + 0.5 * q @ m.Kb @ q \
            + 0.5 * sc[S_KM] * sc[S_COMP] ** 2 \
            + 0.5 * m.p.kr2 * ((y[U2] - y[Y_A]) ** 2 - y[U2] ** 2)
        return {"stored": float(stored), "input": float(y[12]), "damping": float(y[13]),
                "friction": float(y[14]), "parametric": float(y[15])}

    @property
    def rejected_steps(self) -> int:
        """Runge-Kutta step attempts the error test rejected in the last `advance` (work that
        `StepSummary.n_steps` does not count)."""
        return int(self._out[O_NREJ])

    @property
    def stick_time(self) -> float:
        """Time spent with a pair stuck since reset (s)."""
        return float(self._st[T_STICK])

    @property
    def separation_time(self) -> float:
        """Time spent with no flank in contact since reset (s)."""
        return float(self._st[T_SEP])

    @property
    def back_time(self) -> float:
        """Time spent on the back flank since reset (s)."""
        return float(self._st[T_BACK])
