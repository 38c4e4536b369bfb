"""Dense output and event location (compiled).

Unknown switches are found by sampling each accepted step at most ``sample_spacing`` apart
(plus its end) and watching every event function for a fall through zero (DOP853 samples the
cubic Hermite of the step ends first and re-scans on its full continuous extension when
something falls); the earliest fall is refined on the interpolant with the Illinois variant
of regula falsi until the bracket is shorter than ``t_tol`` plus 8 ulp of t; the located
instant is the right end of the bracket (the state has already changed there).
"""

from __future__ import annotations

import math

import numpy as np

from ..engine import G_START
from ..jitcache import jit, jit_hot
from .contact import (
    dte_of,
    evaluate,
    event_values,
    flank_compression,
    n_events,
    n_sep_events,
    pair_k,
    pair_v,
    pair_xi,
    rhs,
    sep_event_values,
)
from .layout import (
    FR_STICK,
    I_BACK,
    I_FRIC,
    I_IX,
    I_METHOD,
    I_NIX,
    J_REL,
    N_Y,
    O_BFAIL,
    O_CFAIL,
    O_DFAIL,
    O_FINT,
    O_FMAX,
    O_FMIN,
    O_STATUS,
    O_TFAIL,
    P_BACK,
    P_DB0,
    P_DB1,
    P_RB1,
    P_SPACING,
    P_TTOL,
    R_GEND,
    R_GSAVE,
    S_COMP,
    S_KM,
    STATUS_MISSED,
    STATUS_OK,
    STATUS_UNBOUNDED,
    T_REL,
    T_S,
)
from .rk import EPS, stage
from .switching import any_stuck, end_piece, switch
from .tableaux import RK_C, RK_D, RK_ND, RK_NS, RK_NX


@jit_hot
def interp(md, R, nf, theta, out):
    """Continuous extension of the accepted step at fraction ``theta``:
    R0 + th (R1 + (1 - th) (R2 + th (R3 + ...))) over rows 1..nf; the components that are
    not integrated (`integrated_components`) are left as they are in ``out``."""
    mi = md.flag
    th1 = 1.0 - theta
    for k in range(mi[I_NIX]):
        m = mi[I_IX + k]
        acc = 0.0
        for i in range(nf, 0, -1):
            acc = (R[i, m] + acc) * (theta if i % 2 == 1 else th1)
        out[m] = R[0, m] + acc


@jit_hot
def hermite(R, y, ynew, K, hh, nfs):
    """Rows 0-3 of the continuous extension (`interp`): alone, the cubic Hermite of the step
    ends (K[0] at the start, K[nfs] at the end); returns its row count."""
    for m in range(N_Y):
        dyn = ynew[m] - y[m]
        R[0, m] = y[m]
        R[1, m] = dyn
        R[2, m] = hh * K[0, m] - dyn
        R[3, m] = 2.0 * dyn - hh * (K[0, m] + K[nfs, m])
    return 3


@jit_hot
def dense_rows(md, R, y, ynew, K, hh):
    """Coefficients of the continuous extension of the step y -> ynew (for `interp`): the
    Hermite rows plus rows of D; for DOP853 the extra stages must be in K already
    (`extend`). Returns the row count."""
    mi = md.flag
    meth = mi[I_METHOD]
    hermite(R, y, ynew, K, hh, RK_NS[meth] - 1)
    nx = RK_NX[meth]
    nd = RK_ND[meth]
    for k in range(mi[I_NIX]):
        m = mi[I_IX + k]
        for r in range(nd):
            acc = 0.0
            for j in range(nx):
                acc += RK_D[meth, r, j] * K[j, m]
            R[4 + r, m] = hh * acc
    return 3 + nd


@jit
def extend(md, wk, pc, hs, sp):
    """Continuous extension of the accepted step ``sp`` into ``wk.dense`` (DOP853 first
    evaluates its three extra stages); returns its row count for `interp`."""
    meth = md.flag[I_METHOD]
    K, hh = wk.stages, sp.hh
    for stg in range(RK_NS[meth], RK_NX[meth]):
        stage(meth, stg, hs.y, K, hh, wk.ytmp)
        rhs(md, wk, pc, hs, sp.t + RK_C[meth, stg] * hh, sp.si, wk.ytmp, K[stg])
    return dense_rows(md, wk.dense, hs.y, wk.ynew, K, hh)


@jit_hot
def record_force(summ, f):
    """Take the mesh force ``f`` (N), a point of the trajectory, into the running least and
    greatest values of the step summary ``summ``."""
    if f > summ[O_FMAX]:
        summ[O_FMAX] = f
    if f < summ[O_FMIN]:
        summ[O_FMIN] = f


@jit
def events_at(md, wk, pc, hs, t, yk, g):
    """Event values at (t, yk) into g, with the full contact-state evaluation; returns the
    mesh force."""
    s = pc.s0 + md.par[P_RB1] * pc.speed * (t - pc.t0)
    evaluate(md, wk, pc, s, s, yk, hs.dirs, hs.stuck)
    event_values(md, wk, pc, hs.dirs, g)
    return wk.scal[S_KM] * wk.scal[S_COMP]


@jit_hot
def events_light(md, wk, pc, hs, t, yk, g):
    """`events_at` where no pair is stuck: the event functions (DTE, slip velocities) and
    the mesh force are then plain expressions of the state, so the forces, the friction and
    the accelerations are not evaluated (the samples inside a step need only these)."""
    mp, sep, act = md.par, pc.cs, wk.active
    if md.flag[I_FRIC] == FR_STICK and sep == 0 and any_stuck(md, hs.stuck):
        return events_at(md, wk, pc, hs, t, yk, g)
    s = pc.s0 + mp[P_RB1] * pc.speed * (t - pc.t0)
    delta = dte_of(yk)
    n = sep_event_values(md, sep, delta, g)
    if md.flag[I_FRIC] == FR_STICK and sep == 0:
        for i in range(pc.nact):
            g[n + i] = hs.dirs[act[i]] * pair_v(md, s, yk, pc.speed, act[i])
    if sep == 1:
        return 0.0
    km = 0.0
    for i in range(pc.nact):
        xi = pair_xi(mp, s, act[i])
        km += pair_k(md, xi, xi, pc.nact)
    return km * flank_compression(mp, delta, sep)


@jit_hot
def dte_noise(y, off):
    """What rounding alone can put into the DTE (``off`` 0) or its rate (``off`` 6) of the
    state y: 64 ulp of the terms summed. Values within it are taken as zero."""
    return 64.0 * EPS * (abs(y[off + 1]) + abs(y[off + 4]) + abs(y[off + 2]) + abs(y[off + 5]))


@jit_hot
def flank_sign(cs, e):
    """+1 where separation function e of contact code cs is +DTE (+ b), -1 where -DTE."""
    return 1.0 if cs == 0 or e == 1 else -1.0


@jit_hot
def start_flanks(md, pc, g, y):
    """The separation functions (flank contact, ``g[:n_sep_events]``) at the start of a
    piece, from state y: returns the first whose switch is due now (below zero beyond
    rounding, where the state contradicts the geometry; or at zero and falling), else -1.

    A function at zero (to rounding) and rising is taken as `engine.G_START`, the least
    positive normal value, so that a fall right after it counts: with 0 as the previous
    value no fall would ever count (the event that ended the last piece can leave the DTE
    at exactly 0.0, and a re-contact microseconds later went unnoticed: issue 38). One at
    zero and at rest (no load, nothing moving) stays as it is: marking it would make
    rounding noise switch back and forth.
    """
    tol, rtol = dte_noise(y, 0), dte_noise(y, 6)
    rate = y[7] - y[10] + y[8] + y[11]
    for e in range(n_sep_events(md, pc.cs)):
        if g[e] < -tol:
            return e
        if g[e] <= 0.0:
            r = flank_sign(pc.cs, e) * rate
            if r > rtol:
                g[e] = G_START
            elif r < -rtol:
                return e
    return np.int64(-1)


@jit_hot
def flank_guard(md, wk, pc, t, y):
    """The check after every accepted step that nothing can skip (issue 38): the contact
    state agrees with the geometry at its end (``wk.g``: the event values there, with no
    fall seen), and neither flank is compressed by more than P_DB0 + P_DB1 |torque|
    (`Model.dte_bound`), at the step's end (time t, state y).

    A separation function below zero (beyond rounding) with no fall seen means a missed
    event: every piece starts with its functions above zero or at zero and rising
    (`start_flanks`), so this cannot happen unless something is wrong; the advance then
    stops (STATUS_MISSED) instead of going on with the teeth overlapping. Returns the
    status, and records the time, DTE, contact code and bound of a failure in the summary.
    """
    mp, summ = md.par, wk.summary
    status = STATUS_OK
    d = dte_of(y)
    for e in range(n_sep_events(md, pc.cs)):
        if wk.g[e] < 0.0 and wk.g[e] < -dte_noise(y, 0):  # the noise only when needed
            status = STATUS_MISSED
    bound = mp[P_DB0] + mp[P_DB1] * abs(pc.torque)  # the most a flank may be compressed
    if not (d <= bound) or (md.flag[I_BACK] != 0 and not (d >= -mp[P_BACK] - bound)):
        status = STATUS_UNBOUNDED
    if status != STATUS_OK:
        summ[O_STATUS] = status
        summ[O_TFAIL] = t
        summ[O_DFAIL] = d
        summ[O_CFAIL] = pc.cs
        summ[O_BFAIL] = bound
    return status


@jit
def mark_missed(md, wk, pc, g0, tol, tol0):
    """Locate and redo (issue 38), the common part: `flank_guard` found flank functions
    below zero (beyond rounding ``tol``) at the end of an accepted step with no fall seen.
    Such a function was at zero or below, never positive, at every sample of the step (a
    positive sample before a value at or below zero is a fall), so it stood at zero at the
    step's start: a state at rest with the flanks just touching, which `start_flanks` leaves
    as it is, driven through zero by a load. Its event lies in the step.

    Each one's start in ``wk.gprev`` becomes `engine.G_START` (a zero counted as positive,
    as `start_flanks` does for one that rises), so that the caller locates its fall as one
    the scan saw and switches there; the rest of the step is then integrated again in the
    new state. The failure the guard recorded is cleared.

    Returns False when it cannot: the failure is not a missed event (the DTE bound), or a
    function was below zero beyond rounding (``tol0``) at the step's start already (``g0``:
    the values there; the state was wrong before the step, nothing in it to locate).
    """
    summ, g = wk.summary, wk.g
    if summ[O_STATUS] != STATUS_MISSED:
        return False
    for e in range(n_sep_events(md, pc.cs)):
        if g[e] < 0.0 and g[e] < -tol:
            if g0[e] < -tol0:
                return False
            wk.gprev[e] = G_START
    for i in (O_STATUS, O_TFAIL, O_DFAIL, O_CFAIL, O_BFAIL):
        summ[i] = 0.0
    return True


@jit
def missed_event(md, wk, pc, hs, sp):
    """`mark_missed` for the accepted Runge-Kutta step ``sp``; builds its continuous
    extension, on which the caller locates the fall over the whole step
    (`locate_and_switch`). Returns the extension's rows, 0 when it cannot."""
    if wk.summary[O_STATUS] != STATUS_MISSED:
        return 0
    tol = dte_noise(wk.ynew, 0)
    nf = extend(md, wk, pc, hs, sp)
    events_at(md, wk, pc, hs, sp.t, hs.y, wk.ynew)  # the values at the step's start
    if not mark_missed(md, wk, pc, wk.ynew, tol, dte_noise(hs.y, 0)):
        return 0
    return nf


@jit_hot
def illinois_point(a, ga, b, gb):
    """Next point of the Illinois (modified regula falsi) search on [a, b], g(a) > 0 >= g(b).

    A left end at a zero taken as positive (`start_flanks`: ``ga`` = G_START) is a root
    itself: the secant would land on it, where g is zero give or take rounding and could
    count as fallen, so the step is a bisection until the left end holds a true value."""
    if ga <= G_START:
        return 0.5 * (a + b)
    c = b - gb * (b - a) / (gb - ga)
    if not (a < c < b):
        c = 0.5 * (a + b)
    return c


@jit_hot
def illinois(a, ga, b, gb, c, gc, side):
    """Shrink the bracket with the value gc at c; halve the stale end's value when the same
    end moves twice (what keeps regula falsi superlinear). Returns a, ga, b, gb, side."""
    if gc <= 0.0:
        if side == -1:
            ga *= 0.5
        return a, ga, c, gc, -1
    if side == 1:
        gb *= 0.5
    return c, gc, b, gb, 1


@jit_hot
def falls(wk, ng):
    """Whether an event function fell through zero between ``wk.gprev`` and ``wk.g``."""
    for e in range(ng):
        if wk.gprev[e] > 0.0 and wk.g[e] <= 0.0:
            return True
    return False


@jit_hot
def prepare_scan(md, wk, pc, hs, sp, nsub):
    """Before sampling a step in ``nsub`` parts: keep the event values at its end (its last
    stage was evaluated there) and build the extension to sample on (DOP853: the cheap
    Hermite first). Returns (rows of the extension, cheap, mesh force at the end)."""
    meth = md.flag[I_METHOD]
    R, g, ns = wk.dense, wk.g, RK_NS[meth]
    ng = n_events(md, pc.nact, pc.cs)
    if nsub <= 1:
        return 0, False, 0.0
    event_values(md, wk, pc, hs.dirs, g)
    fm_end = wk.scal[S_KM] * wk.scal[S_COMP]
    for e in range(ng):
        R[R_GEND, e] = g[e]
    if RK_NX[meth] > ns:
        for e in range(ng):
            R[R_GSAVE, e] = wk.gprev[e]
        return hermite(R, hs.y, wk.ynew, wk.stages, sp.hh, ns - 1), True, fm_end
    return extend(md, wk, pc, hs, sp), False, fm_end


@jit_hot
def scan_samples(md, wk, pc, hs, sp, nsub, nf, fm_end):
    """Sample the step at ks / nsub on the extension (rows ``nf``); record the mesh force
    at the samples before a fall. Returns (hit, theta of the last sample before the fall,
    theta of the fall)."""
    g, R, ng = wk.g, wk.dense, n_events(md, pc.nact, pc.cs)
    summ = wk.summary
    th_prev = 0.0
    for ks in range(1, nsub + 1):
        if ks == nsub:
            th = 1.0
            if nsub == 1:
                event_values(md, wk, pc, hs.dirs, g)
                fm = wk.scal[S_KM] * wk.scal[S_COMP]
            else:
                for e in range(ng):
                    g[e] = R[R_GEND, e]
                fm = fm_end
        else:
            th = ks / nsub
            interp(md, R, nf, th, wk.ytmp)
            fm = events_light(md, wk, pc, hs, sp.t + th * sp.hh, wk.ytmp, g)
        if falls(wk, ng):  # the force there is the old state's, past the switch
            return True, th_prev, th
        if ks == nsub or nf > 3:
            # the step's end, or a point of its continuous extension (not of DOP853's cheap
            # Hermite, which can overshoot): `extremes` finds the turns in between
            record_force(summ, fm)
        for e in range(ng):
            wk.gprev[e] = g[e]
        th_prev = th
    return False, th_prev, 1.0


@jit_hot
def scan_step(md, wk, pc, hs, sp):
    """Scan the accepted step for falls through zero, samples at most `spacing` apart.

    The continuous extension is needed only to sample inside the step. DOP853's costs three
    more stages, so its samples are first taken on the cubic Hermite of the step ends; a
    fall seen there is re-scanned on the full extension (the end values are exact either
    way, so a single crossing is always caught). Returns (hit, rows of the extension, theta
    before the fall, theta of the fall).
    """
    nsub = int(math.ceil(sp.hh / md.par[P_SPACING] * (1.0 - 1e-12)))
    if nsub < 1:
        nsub = 1
    nf, cheap, fm_end = prepare_scan(md, wk, pc, hs, sp, nsub)
    ng = n_events(md, pc.nact, pc.cs)
    while True:
        hit, th_prev, th_hit = scan_samples(md, wk, pc, hs, sp, nsub, nf, fm_end)
        if not (hit and cheap):
            break
        nf = extend(md, wk, pc, hs, sp)
        cheap = False
        for e in range(ng):
            wk.gprev[e] = wk.dense[R_GSAVE, e]
    if hit and nsub == 1:
        nf = extend(md, wk, pc, hs, sp)
    return hit, nf, th_prev, th_hit


@jit
def refine(md, wk, pc, hs, sp, nf, e, bracket):
    """Illinois on the interpolant for event function e over the bracket (theta before,
    theta after its fall); returns the right end of the final bracket."""
    a, b = bracket
    ga, gb = wk.gprev[e], wk.g[e]
    tol_th = (md.par[P_TTOL] + 8.0 * EPS * abs(sp.t)) / sp.hh
    side = np.int64(0)
    for _it in range(200):
        if b - a <= tol_th:
            break
        c = illinois_point(a, ga, b, gb)
        interp(md, wk.dense, nf, c, wk.ytmp)
        events_at(md, wk, pc, hs, sp.t + c * sp.hh, wk.ytmp, wk.ynew)
        a, ga, b, gb, side = illinois(a, ga, b, gb, c, wk.ynew[e], side)
    return b


# Gauss-Legendre nodes and weights on [0, 1] (3 points, exact to degree 5): the mesh force
# integral over a step cut short by an event, on its continuous extension
GL3_X = np.array([0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6)])
GL3_W = np.array([5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0])


@jit
def force_integral(md, wk, pc, hs, sp, nf, th):
    """Mean mesh force over the fraction ``th`` of step ``sp`` up to a switch: Gauss-Legendre
    on the continuous extension (the stage quadrature covers whole steps only)."""
    fi = 0.0
    for gi in range(3):
        interp(md, wk.dense, nf, GL3_X[gi] * th, wk.ytmp)
        fi += GL3_W[gi] * events_at(md, wk, pc, hs, sp.t + GL3_X[gi] * th * sp.hh, wk.ytmp,
                                    wk.ynew)
    return fi


@jit
def locate_and_switch(md, wk, pc, hs, sp, nf, th_prev, th_hit):
    """Refine every falling function on the interpolant; at the earliest, move the state
    there, end the piece and switch."""
    best_th = th_hit
    best_e = np.int64(-1)
    for e in range(n_events(md, pc.nact, pc.cs)):
        if not (wk.gprev[e] > 0.0 and wk.g[e] <= 0.0):
            continue
        b = refine(md, wk, pc, hs, sp, nf, e, (th_prev, th_hit))
        if best_e < 0 or b < best_th:
            best_th, best_e = b, e
    te = sp.t + best_th * sp.hh
    if best_th >= 1.0:
        te = sp.tn
    wk.summary[O_FINT] += force_integral(md, wk, pc, hs, sp, nf, best_th) * (te - sp.t)
    interp(md, wk.dense, nf, best_th, wk.ytmp)
    for m in range(N_Y):
        hs.y[m] = wk.ytmp[m]
    end_piece(md, pc, hs, te)
    hs.mode[J_REL] = 0
    switch(md, wk, pc, hs, best_e, hs.clock[T_S])
    if hs.mode[J_REL] != 0:
        hs.clock[T_REL] = te
