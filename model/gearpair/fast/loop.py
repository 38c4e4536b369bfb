"""The segment and advance loop (compiled): `ReferenceEngine.advance` in numba.

*Known* discontinuities (a pair entering or leaving the path of contact; the pitch point for
the nominal friction law) are segment boundaries computed from the mesh travel
``s = rb1 * speed * t``; the stored mesh energy that jumps there is booked as parametric
work. Inside a segment, pieces of one contact state are integrated (`piece`: Runge-Kutta,
or `lti.piece_lti`) up to the first switch, which is applied before the next piece.

The entry points called from Python (``*_entry``) take the records as plain tuples, which
numba types faster per call than named ones, and name them.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine import CONTACT_BACK, CONTACT_SEPARATED, CONTACT_SLIP, CONTACT_STICK
from ..jitcache import jit, jit_entry, jit_hot
from .contact import (
    active_at,
    evaluate,
    n_events,
    n_sep_events,
    next_knot_dt,
    pair_k,
    pair_xi,
    param_rate,
)
from .events import (
    events_at,
    flank_guard,
    locate_and_switch,
    missed_event,
    record_force,
    scan_step,
    start_flanks,
)
from .extremes import step_ends, step_extremes
from .layout import (
    FR_NOMINAL,
    FR_STICK,
    I_FRIC,
    I_KIND,
    I_LTI,
    I_MAXEV,
    I_METHOD,
    I_NP,
    J_NEVTOT,
    J_NPREV,
    J_REL,
    J_RESUME,
    J_SEP,
    KIND_CONSTANT,
    KIND_TABLE,
    N_O,
    N_OUT,
    N_Y,
    O_FINT,
    O_FMAX,
    O_FMIN,
    O_NEV,
    O_NSTEPS,
    O_STATUS,
    O_TFAIL,
    P_C,
    P_CM,
    P_KB,
    P_L,
    P_PB,
    P_RATIO,
    P_RB1,
    P_RB2,
    P_XIP,
    R_FSTG,
    S_COMP,
    S_DDELTA,
    S_DELTA,
    S_KM,
    S_THETA,
    STATUS_EVENTS,
    STATUS_OK,
    STATUS_STEP,
    T_BACK,
    T_H,
    T_REL,
    T_S,
    T_SEP,
    T_SPEED,
    T_STICK,
    T_T,
    T_TORQUE,
    W_F,
    W_S1M,
    W_V,
    W_XI,
    Y_A,
    Y_AD,
    HybridState,
    ModelData,
    Piece,
    Work,
)
from .lti import piece_lti
from .rk import first_step, try_step
from .start import reset_state
from .switching import end_piece, settle, speed_change, switch
from .tableaux import RK_A, RK_NS


@jit_hot
def start_checks(md, wk, pc, hs):
    """Events at the start of a piece, and the switches due there; returns 1 after one.

    A known boundary can invalidate a stick at once (the entering pair takes load, so
    mu f_mesh drops below the static friction): release it before integrating.
    """
    st, stuck, act, gprev = hs.clock, hs.stuck, wk.active, wk.gprev
    fm = events_at(md, wk, pc, hs, pc.t0, hs.y, gprev)
    record_force(wk.summary, fm)
    e = start_flanks(md, pc, gprev, hs.y)
    if e >= 0:  # a flank in tension, or overlapping flanks apart: that switch is due now
        switch(md, wk, pc, hs, e, pc.s0)
        return 1
    e0 = n_sep_events(md, pc.cs)
    retest = False
    for e in range(e0, n_events(md, pc.nact, pc.cs)):
        j = act[e - e0]
        if stuck[j] != 0 and gprev[e] < 0.0:
            switch(md, wk, pc, hs, e, pc.s0)
            st[T_REL] = pc.t0
            return 1
        if stuck[j] == 0 and gprev[e] == 0.0 and not (
                hs.mode[J_REL] == j + 1 and st[T_REL] == pc.t0):
            # A slipping pair exactly at v = 0 (a start at rest, standstill): no fall through
            # zero will ever be seen, so apply Eq. (14) now. If it cannot stick it keeps the
            # direction the dynamics carry v to, and integration goes on.
            switch(md, wk, pc, hs, e, pc.s0)
            if stuck[j] != 0:
                return 1
            retest = True
    if retest:
        events_at(md, wk, pc, hs, pc.t0, hs.y, gprev)
        e = start_flanks(md, pc, gprev, hs.y)  # the rates may have changed
        if e >= 0:
            switch(md, wk, pc, hs, e, pc.s0)
            return 1
    return 0


@jit_hot
def accept_step(md, wk, pc, hs, sp, h, t_knot, tb):
    """Take the accepted step ``sp`` (FSAL: its last stage is the next first); at a knot,
    find the next one. Returns (t, t_knot)."""
    y, K, R = hs.y, wk.stages, wk.dense
    meth = md.flag[I_METHOD]
    ns = RK_NS[meth]
    fi = 0.0
    for j in range(ns - 1):  # the weights b: the last row of A (first same as last)
        fi += RK_A[meth, ns - 1, j] * R[R_FSTG, j]
    wk.summary[O_FINT] += sp.hh * fi
    R[R_FSTG, 0] = R[R_FSTG, ns - 1]
    for m in range(N_Y):
        y[m] = wk.ynew[m]
        K[0, m] = K[ns - 1, m]
    t = sp.tn
    if sp.last:
        end_piece(md, pc, hs, tb)
    elif sp.at_knot:
        v1 = md.par[P_RB1] * pc.speed
        t_knot = t + next_knot_dt(md, pc.s0 + v1 * (t - pc.t0), pc.speed, wk.active, pc.nact)
        if md.flag[I_KIND] == KIND_TABLE:
            # next table interval: the parametric power changes its slope there (a
            # spline's slope is continuous at its knots)
            si = pc.s0 + v1 * (t + 0.5 * min(h, t_knot - t, tb - t) - pc.t0)
            K[0, 15] = param_rate(md, wk, pc, si, y)
    return t, t_knot


@jit_hot
def piece_at(hs, nact):
    """The `Piece` starting at the current state with the ``nact`` pairs of `Work.active`."""
    st = hs.clock
    return Piece(st[T_T], st[T_S], st[T_TORQUE], st[T_SPEED], nact, hs.mode[J_SEP])


@jit_hot
def piece(md, wk, hs, nact, tb):
    """Integrate one contact state from clock[T_T] towards tb by Runge-Kutta steps; stop at
    the first switch. Returns 1 after a switch, 0 on reaching tb, -1 on a step-size failure,
    -2 when `flank_guard` stops it (its status is in the summary): a missed event it finds
    is located and switched instead (`events.missed_event`), unless that cannot be done.
    """
    st = hs.clock
    pc = piece_at(hs, nact)
    if start_checks(md, wk, pc, hs) != 0:
        return 1
    h, t_knot = first_step(md, wk, pc, hs, tb)
    t = pc.t0
    d0 = np.nan  # dF/dt at the next step's start, once known (`step_ends`)
    while True:
        status, h, t_knot, sp = try_step(md, wk, pc, hs, t, h, t_knot, tb)
        if status <= 0:
            return status
        wk.summary[O_NSTEPS] += 1.0
        st[T_H] = h
        ends = step_ends(md, wk, pc, hs, sp, d0)
        fmax, fmin = wk.summary[O_FMAX], wk.summary[O_FMIN]
        hit, nf, th_prev, th_hit = scan_step(md, wk, pc, hs, sp)
        if not hit and flank_guard(md, wk, pc, sp.tn, wk.ynew) != STATUS_OK:
            # a missed event: locate it in this step and redo the rest from there; the
            # scan recorded forces of the wrong state, past the event: drop them
            nf = missed_event(md, wk, pc, hs, sp)
            if nf == 0:
                return -2
            wk.summary[O_FMAX], wk.summary[O_FMIN] = fmax, fmin
            hit, th_prev, th_hit = True, 0.0, 1.0
        if hit:
            locate_and_switch(md, wk, pc, hs, sp, nf, th_prev, th_hit)
            step_extremes(md, wk, pc, hs, sp, nf, ends, (st[T_T] - sp.t) / sp.hh)
            return 1
        step_extremes(md, wk, pc, hs, sp, nf, ends, 1.0)
        d0 = np.nan if sp.at_knot else ends[3]
        t, t_knot = accept_step(md, wk, pc, hs, sp, h, t_knot, tb)
        if sp.last:
            return 0


@jit_hot
def piece_exact(md, wk, hs, nact, tb):
    """`piece` by the exact propagator (`lti.piece_lti`; no friction: only the separation
    events). Inlined into `segment` beside `piece`: a call would pass the records by value
    once per piece, some 7 % of an exact-propagator step."""
    return piece_lti(md, wk, piece_at(hs, nact), hs, tb)


@jit
def release_departed(md, wk, hs, nact):
    """Pairs that left contact are no longer stuck."""
    for j in range(md.flag[I_NP]):
        inside = False
        for i in range(nact):
            if wk.active[i] == j:
                inside = True
        if not inside:
            hs.stuck[j] = 0


@jit
def book_pair_change(md, wk, hs, nact):
    """Stored mesh energy jumps when a pair enters or leaves: book it as parametric (the
    constant law keeps its total whichever pairs are in mesh)."""
    st, y, sc = hs.clock, hs.y, wk.scal
    nprev = hs.mode[J_NPREV]
    km_before = 0.0
    for i in range(nprev):
        xi = pair_xi(md.par, st[T_S], hs.prev_active[i])
        km_before += pair_k(md, xi, xi, nprev)
    evaluate(md, wk, piece_at(hs, nact), st[T_S], st[T_S], y, hs.dirs, hs.stuck)
    y[15] += 0.5 * (sc[S_KM] - km_before) * sc[S_COMP] ** 2


@jit_hot
def segment_start(md, wk, hs, tb, fresh):
    """The pair set of the segment ending at tb, and what changes with it; returns its size.
    ``fresh``: False when the segment goes on after an early return (`segment_early`)."""
    st = hs.clock
    speed = st[T_SPEED]
    s_mid = st[T_S] + md.par[P_RB1] * speed * (0.5 * (st[T_T] + tb) - st[T_T])
    nudge = 1e-9 * md.par[P_PB]
    if abs(s_mid - st[T_S]) < nudge and speed != 0.0:
        # a (near) zero-length segment sits on a boundary: take the set after it, so a step
        # ending on a pair entry reports the new set whichever side rounding put it
        s_mid = st[T_S] + (nudge if speed > 0.0 else -nudge)
    nact = active_at(md, s_mid, wk.active)
    nprev = hs.mode[J_NPREV]
    if nprev >= 0:
        release_departed(md, wk, hs, nact)
    if fresh:  # else the pairs' slip directions are those the last switch set (a pair just
        # released slips the way its friction pushed, whatever the sign of its velocity, 0
        # to rounding)
        settle(md, hs, wk.active, nact, st[T_S], speed, hs.mode[J_SEP])
    if nprev >= 0 and md.flag[I_KIND] != KIND_CONSTANT and not same_pairs(wk, hs, nact):
        book_pair_change(md, wk, hs, nact)
    return nact


@jit_hot
def same_pairs(wk, hs, nact):
    """Whether the segment's pairs are those of the last one (then no stored energy jumps)."""
    if hs.mode[J_NPREV] != nact:
        return False
    for i in range(nact):
        if hs.prev_active[i] != wk.active[i]:
            return False
    return True


@jit_hot
def keep_pairs(wk, hs, nact):
    """The segment's pairs become those of the last segment."""
    for i in range(nact):
        hs.prev_active[i] = wk.active[i]
    hs.mode[J_NPREV] = nact


@jit_hot
def stops_early(wk, hs, nact, early, cs):
    """Whether an early return ends the step here: the contact state (`contact_state`) is no
    longer ``cs`` and the time is strictly inside ``early`` = (step start, step end).
    Returns (stop, the contact state now)."""
    c = contact_state(wk, hs, nact)
    t = hs.clock[T_T]
    return c != cs and early[0] < t < early[1], c


@jit_hot
def booked_piece(md, wk, hs, nact, tb, lti):
    """One piece (`piece_exact` where ``lti``, else `piece`) with its events booked in the
    summary. Returns the piece's code (1: it ended at a switch, 0: at ``tb``), or -1 when
    the segment must end: the piece failed, or the events exceeded ``max_events`` (the
    summary's status says which)."""
    summ = wk.summary
    if not lti:
        r = piece(md, wk, hs, nact, tb)
    else:
        r = piece_exact(md, wk, hs, nact, tb)
    if r < 0:
        if r == -1:
            summ[O_STATUS] = STATUS_STEP
        return -1
    summ[O_NEV] += r
    if summ[O_NEV] > md.flag[I_MAXEV]:
        summ[O_STATUS] = STATUS_EVENTS
        summ[O_TFAIL] = hs.clock[T_T]
        return -1
    return r


@jit_hot
def segment(md, wk, hs, tb, lti):
    """One segment between known boundaries (ReferenceEngine.advance's loop body); ``lti``:
    by the exact propagator (`piece_exact`) rather than Runge-Kutta (`piece`)."""
    nact = segment_start(md, wk, hs, tb, True)
    while hs.clock[T_T] < tb:
        if booked_piece(md, wk, hs, nact, tb, lti) < 0:
            return
    keep_pairs(wk, hs, nact)


@jit
def segment_early(md, wk, hs, tb, lti, early, cs):
    """`segment` in a step that may return early (`advance`), ``cs`` the contact state before
    the segment. Returns (stopped, the contact state): stopped at the first change of the
    contact state (at a switch, or at the segment's start when a pair leaving released a
    stick), with the segment's pairs kept and J_RESUME set for the step that goes on from
    there. Until it stops it computes what `segment` computes. A function of its own, not
    inlined: `segment`, the hot path, stays as it is without early return."""
    fresh = hs.mode[J_RESUME] == 0
    hs.mode[J_RESUME] = 0
    nact = segment_start(md, wk, hs, tb, fresh)
    stop, cs = stops_early(wk, hs, nact, early, cs)
    if stop:
        keep_pairs(wk, hs, nact)
        hs.mode[J_RESUME] = 1
        return True, cs
    while hs.clock[T_T] < tb:
        r = booked_piece(md, wk, hs, nact, tb, lti)
        if r < 0:
            return False, cs
        if r == 1:
            stop, cs = stops_early(wk, hs, nact, early, cs)
            if stop:
                keep_pairs(wk, hs, nact)
                hs.mode[J_RESUME] = 1
                return True, cs
    keep_pairs(wk, hs, nact)
    return False, cs


@jit_hot
def current_active(md, wk, hs):
    """The pairs of the last segment (a state on a boundary keeps its set), else the set at
    the current mesh travel, into wk.active; returns their number."""
    npv = hs.mode[J_NPREV]
    if npv >= 0:
        for i in range(npv):
            wk.active[i] = hs.prev_active[i]
        return npv
    return active_at(md, hs.clock[T_S], wk.active)


@jit_hot
def first_boundaries(md, wk, hs):
    """Offsets of the known boundaries in a base pitch (pair entry, pair exit, the pitch
    point for nominal friction) and the index of the next one of each kind ahead of the
    current mesh travel; returns how many kinds there are."""
    mp, mi, offs, kcur = md.par, md.flag, wk.bound_offs, wk.bound_k
    speed, s_start, pb = hs.clock[T_SPEED], hs.clock[T_S], md.par[P_PB]
    noff = 3 if mi[I_FRIC] == FR_NOMINAL else 2
    if mi[I_LTI] != 0 and mi[I_KIND] == KIND_CONSTANT:
        noff = 0  # no friction and the same total stiffness whichever pairs are in mesh
    offs[0] = 0.0
    offs[1] = np.fmod(mp[P_L], pb)
    offs[2] = np.fmod(mp[P_XIP], pb)
    if speed != 0.0:
        for i in range(noff):
            if speed > 0.0:
                k = math.floor((s_start - offs[i]) / pb)
                while k * pb + offs[i] <= s_start:
                    k += 1
            else:
                k = math.ceil((s_start - offs[i]) / pb)
                while k * pb + offs[i] >= s_start:
                    k -= 1
            kcur[i] = k
    return noff


@jit_hot
def next_boundary(md, wk, hs, noff, span, last_b):
    """The end of the next segment: the next known boundary before the end of the step
    (``span``: t and s at the step's start, its end t_end and the travel limit s_lim).

    Returns (tb, its kind or -1 at t_end, the boundary's travel, repeat): repeat when the
    boundary of one kind coincides with the last one (skip it).
    """
    t_start, s_start, t_end, s_lim = span
    speed = hs.clock[T_SPEED]
    if speed == 0.0:
        return t_end, -1, last_b, False
    pb, offs, kcur = md.par[P_PB], wk.bound_offs, wk.bound_k
    fwd = speed > 0.0
    ib = -1
    bb = 0.0
    for i in range(noff):
        b = kcur[i] * pb + offs[i]
        if ib < 0 or (fwd and b < bb) or ((not fwd) and b > bb):
            ib, bb = i, b
    if not ((fwd and bb < s_lim) or ((not fwd) and bb > s_lim)):
        return t_end, -1, last_b, False
    kcur[ib] += 1 if fwd else -1
    if bb == last_b:
        return t_end, ib, last_b, True
    tb = t_start + (bb - s_start) / (md.par[P_RB1] * speed)
    tb = min(max(tb, hs.clock[T_T]), t_end)
    if ib < 0:
        tb = t_end
    return tb, ib, bb, False


@jit_hot
def advance(md, wk, hs, t_end, torque, speed, early):
    """ReferenceEngine.advance: segments between the known boundaries, then t_end.

    The engine's flag I_LTI says whether its pieces go by the exact propagator
    (`piece_exact`) or by Runge-Kutta (`piece`): a test at run time, so that one compiled
    step serves both kinds of engine (a compile per kind took a quarter of a first compile).
    Inlined into `native.step`, its one caller, at one call site for a single step and
    for a recorded run alike: a second copy would be optimized by LLVM once more with
    everything it calls.

    ``early``: None (numba then compiles no early return: the engine's own steps and the
    FMI 2 FMU), or (NaN, NaN), or for an FMU's early return (the step's start, t_end): the
    advance then ends at the first change of the contact state strictly inside the step,
    with the switch applied (`segment_early`); the clock says where. Until that change it
    computes what it computes without early return, to the bit.
    """
    st, summ = hs.clock, wk.summary
    lti = md.flag[I_LTI] != 0
    for i in range(N_OUT):
        summ[i] = 0.0
    summ[O_FMAX] = -np.inf
    summ[O_FMIN] = np.inf
    if speed != st[T_SPEED] and md.flag[I_FRIC] == FR_STICK and hs.mode[J_SEP] == 0:
        nact = current_active(md, wk, hs)
        speed_change(md, wk, hs, nact, torque, speed, t_end - st[T_T])
    st[T_TORQUE] = torque
    st[T_SPEED] = speed
    t_start, s_start = st[T_T], st[T_S]
    v1 = md.par[P_RB1] * speed
    noff = first_boundaries(md, wk, hs)
    s_end = s_start + v1 * (t_end - t_start)
    # boundaries a rounding error past the end of the step count as inside it (see segment)
    s_tol = abs(v1) * 16.0 * 2.220446049250313e-16 * max(1.0, abs(t_end))
    s_lim = s_end + s_tol if speed > 0.0 else s_end - s_tol
    last_b = np.nan
    watch = False
    cs = -1
    if early is not None:  # numba prunes this branch for early None
        watch = early[0] == early[0]  # not NaN
        if watch:  # the contact state at the step's start
            cs = contact_state(wk, hs, current_active(md, wk, hs))
    if not watch:  # a segment an early return cut is gone on with like any other
        hs.mode[J_RESUME] = 0
    while True:
        tb, ib, last_b, repeat = next_boundary(md, wk, hs, noff,
                                               (t_start, s_start, t_end, s_lim), last_b)
        if repeat:
            continue
        if early is not None and watch:
            stopped, cs = segment_early(md, wk, hs, tb, lti, early, cs)
            if stopped and summ[O_STATUS] == STATUS_OK:
                hs.mode[J_NEVTOT] += int(summ[O_NEV])
                return
        else:
            segment(md, wk, hs, tb, lti)
        if summ[O_STATUS] != STATUS_OK:
            return
        if ib < 0:
            break
    st[T_T] = t_end
    hs.mode[J_NEVTOT] += int(summ[O_NEV])


@jit_hot
def eval_now(md, wk, hs):
    """Evaluate at the current state (active set of the last segment); returns nact."""
    st = hs.clock
    nact = current_active(md, wk, hs)
    evaluate(md, wk, piece_at(hs, nact), st[T_S], st[T_S], hs.y, hs.dirs, hs.stuck)
    return nact


@jit_hot
def contact_state(wk, hs, nact):
    """The `Outputs.contact_state` code of the current state."""
    cs = hs.mode[J_SEP]
    if cs == 2:
        return CONTACT_BACK
    if cs == 1:
        return CONTACT_SEPARATED
    state = CONTACT_SLIP
    for i in range(nact):
        if hs.stuck[wk.active[i]] != 0:
            state = CONTACT_STICK
    return state


@jit_hot
def outputs_now(md, wk, hs):
    """`Outputs` at the current state into ``wk.outputs`` (compiled: the FMU reads them
    every step)."""
    nact = eval_now(md, wk, hs)
    mp, pw, sc, y, o = md.par, wk.pair, wk.scal, hs.y, wk.outputs
    rb1, rb2 = mp[P_RB1], mp[P_RB2]
    mesh = sc[S_KM] * sc[S_COMP]
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
    speed = hs.clock[T_SPEED]
    o[0] = sc[S_DELTA]
    o[1] = mesh
    o[2] = fr
    o[3] = contact_state(wk, hs, nact)
    o[4] = -rb2 * (mp[P_KB + 5] * (y[5] - y[Y_A]) + mp[P_C + 5] * (y[11] - y[Y_AD]))
    o[5] = rb1 * (mesh + damp) - fm
    o[6] = hs.clock[T_TORQUE] - rb1 * (mp[P_KB + 2] * y[2] + mp[P_C + 2] * y[8])
    o[7] = speed + y[8] / rb1
    o[8] = speed * mp[P_RATIO] - y[11] / rb2
    o[9] = pw[W_V, i_near] if nact > 0 else 0.0


@jit_hot
def record_first(md, wk, hs, rec):
    """Column 0 of a recorded run's ``rec`` (`native.step`'s recorded run, for
    `FastEngine.run`): the outputs at its start; the force extremes and mean are the force
    there, the rates zero."""
    o = wk.outputs
    outputs_now(md, wk, hs)
    for m in range(N_O):
        rec[m, 0] = o[m]
    rec[N_O + 2, 0] = o[1]
    rec[N_O + 5, 0] = o[1]
    rec[N_O + 6, 0] = o[1]


@jit_hot
def record_row(md, wk, hs, rec, i, start):
    """Column ``i`` of a recorded run's ``rec`` after the advance to its time: the outputs
    there and the figures of the interval (``start``: time, stick, separation and
    back-flank times at the interval's start)."""
    st, o, summ = hs.clock, wk.outputs, wk.summary
    outputs_now(md, wk, hs)
    h = st[T_T] - start[0]
    for m in range(N_O):
        rec[m, i] = o[m]
    rec[N_O, i] = (st[T_STICK] - start[1]) / h
    rec[N_O + 1, i] = (st[T_SEP] - start[2]) / h
    rec[N_O + 2, i] = max(summ[O_FMAX], o[1])
    rec[N_O + 3, i] = summ[O_NEV]
    rec[N_O + 4, i] = (st[T_BACK] - start[3]) / h
    rec[N_O + 5, i] = summ[O_FINT] / h
    rec[N_O + 6, i] = min(summ[O_FMIN], o[1])


@jit
def reset_settle(md, wk, hs):
    """Slip directions of the pairs in contact at a reset state."""
    st = hs.clock
    nact = active_at(md, st[T_S], wk.active)
    settle(md, hs, wk.active, nact, st[T_S], st[T_SPEED], hs.mode[J_SEP])


# -- entry points from Python: plain tuples in, named records inside ------------------------
@jit_entry
def outputs_entry(md, wk, hs):
    outputs_now(ModelData(*md), Work(*wk), HybridState(*hs))


@jit_entry
def eval_entry(md, wk, hs):
    return eval_now(ModelData(*md), Work(*wk), HybridState(*hs))


@jit_entry
def reset_entry(md, wk, hs, start):
    """`start.reset_state` and the slip directions (`reset_settle`); the solver's status."""
    md, wk, hs = ModelData(*md), Work(*wk), HybridState(*hs)
    status = reset_state(md, wk, hs, start)
    reset_settle(md, wk, hs)
    return status
