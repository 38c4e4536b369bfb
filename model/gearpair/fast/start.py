"""The engine's state at a reset: at rest, or in the static equilibrium under the torque.

`reset_state` is the whole reset of `FastEngine.reset` compiled, so that the FMU's C layer
initializes an engine without Python: the clock and the held inputs, the pairs in contact
at mesh travel 0 and their stiffness (as `gearpair.equations.Model.contact` gives them),
the static deflection ``(Kb + km g g^T) q = Ft`` (`Model.static_deflection`: on the back
flank under a negative torque with backlash; torsional: x and y stay 0), the contact code of
that deflection (`Model.contact_code`), slip directions 1 and no pair stuck. The slip
directions of the pairs in contact are settled afterwards by the caller (`loop.reset_settle`).
"""

from __future__ import annotations

import math

from ..jitcache import jit
from .contact import dte_of
from .detlinalg import OK, solve_into
from .layout import (
    I_BACK,
    I_KIND,
    I_NP,
    I_NTAB,
    I_SEP,
    I_TORS,
    J_NPREV,
    J_SEP,
    KIND_CONSTANT,
    KIND_CUBIC,
    L_SCRATCH,
    N_Q,
    P_BACK,
    P_KB,
    P_KMEAN,
    P_L,
    P_PB,
    P_PER,
    P_RB1,
    T_LAST0,
    T_LAST1,
    T_SPEED,
    T_T,
    T_TORQUE,
)


@jit
def interp(x, xp, fp):
    """numpy's ``interp(x, xp, fp)`` for one x, with its arithmetic (the same bits)."""
    n = xp.shape[0]
    if x > xp[n - 1]:
        return fp[n - 1]
    if x < xp[0]:
        return fp[0]
    j = 0
    lo, hi = 0, n  # the last j with xp[j] <= x
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    j = lo
    if j == n - 1 or xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    r = slope * (x - xp[j]) + fp[j]
    if math.isnan(r):
        r = slope * (x - xp[j + 1]) + fp[j + 1]
        if math.isnan(r) and fp[j] == fp[j + 1]:
            r = fp[j]
    return r


@jit
def rest_stiffness(md, xi, nact):
    """Stiffness (N/m) of a pair at ``xi`` (m from A) among ``nact`` in contact
    (`gearpair.stiffness.MeshStiffness.pairs`)."""
    kind = md.flag[I_KIND]
    if kind == KIND_CONSTANT:
        return md.par[P_KMEAN] / max(nact, 1)
    if kind == KIND_CUBIC:
        x, c = md.xi_knots, md.k_coef
        h = x[1] - x[0]
        i = min(max(int(math.floor(xi / h)), 0), md.flag[I_NTAB] - 2)
        d = xi - x[i]
        return ((c[4 * i + 3] * d + c[4 * i + 2]) * d + c[4 * i + 1]) * d + c[4 * i]
    return interp(xi, md.xi_knots, md.k_coef)


@jit
def rest_contact(md, active):
    """The pairs in contact at mesh travel 0 into ``active``; returns (their number, their
    total stiffness km (N/m), summed in order)."""
    mp = md.par
    pb, per, L = mp[P_PB], mp[P_PER], mp[P_L]
    nact = 0
    for j in range(md.flag[I_NP]):
        xi = (0.0 + j * pb) % per  # numpy's mod (Python's: the sign of the divisor)
        if xi >= 0.0 and xi < L:
            active[nact] = j
            nact += 1
    km = 0.0
    for a in range(nact):
        xi = (0.0 + active[a] * pb) % per
        if xi > 0.5 * (L + per):
            xi = xi - per
        xi = min(max(xi, 0.0), L)
        km += rest_stiffness(md, xi, nact)
    return nact, km


@jit
def static_deflection(md, wk, torque, km, q):
    """The static equilibrium q (m) under ``torque`` with mesh stiffness ``km`` into ``q``
    (`gearpair.equations.Model.static_deflection`); returns the solver's status."""
    mp = md.par
    g = (0.0, 1.0, 1.0, 0.0, -1.0, 1.0)
    tors = md.flag[I_TORS] != 0
    n = 2 if tors else 6
    A, W = wk.lti_mats[L_SCRATCH], wk.lti_mats[L_SCRATCH + 1]
    b, x = wk.lti_vecs[0], wk.lti_vecs[1]
    back = torque < 0.0 and md.flag[I_BACK] != 0
    for a in range(n):
        i = 2 + 3 * a if tors else a  # the torsional model keeps u1, u2
        f = torque / mp[P_RB1] if i == 2 else 0.0
        b[a] = f - km * mp[P_BACK] * g[i] if back else f
        for c in range(n):
            j = 2 + 3 * c if tors else c
            A[a, c] = (mp[P_KB + i] if i == j else 0.0) + km * (g[i] * g[j])
    st = solve_into(A[:n, :n], b[:n], x[:n], W[:n, :n + 1])
    for i in range(N_Q):
        q[i] = 0.0
    for a in range(n):
        q[2 + 3 * a if tors else a] = x[a]
    return st


@jit
def reset_state(md, wk, hs, start):
    """Reset the engine to ``start`` = (t0 (s), torque (N.m), speed (rad/s), static: the
    static equilibrium under the torque, else at rest); returns the solver's status (OK)."""
    t0, torque, speed, static = start
    st, y, mode = hs.clock, hs.y, hs.mode
    for i in range(st.shape[0]):
        st[i] = 0.0
    st[T_T], st[T_TORQUE], st[T_SPEED] = t0, torque, speed
    st[T_LAST0], st[T_LAST1] = math.nan, math.nan
    for i in range(y.shape[0]):
        y[i] = 0.0
    nact, km = rest_contact(md, hs.prev_active)
    status = OK
    if static and torque != 0.0:
        status = static_deflection(md, wk, torque, km, y)
    delta = dte_of(y)
    for i in range(mode.shape[0]):
        mode[i] = 0
    code = 0  # `Model.contact_code`: drive flank, apart, back flank
    if not (delta >= 0.0 or md.flag[I_SEP] == 0):
        code = 2 if md.flag[I_BACK] != 0 and delta < -md.par[P_BACK] else 1
    mode[J_SEP], mode[J_NPREV] = code, nact
    for j in range(hs.dirs.shape[0]):
        hs.dirs[j] = 1.0
        hs.stuck[j] = 0
    return status
