"""The switching rules (compiled), as `gearpair.switching`: slip directions, the Eq. (14)
stick test, releases, separation and re-contact, the speed-change rule, and the bookkeeping
of the time spent in stick and apart."""

from __future__ import annotations

from ..jitcache import jit, jit_hot
from .contact import evaluate, n_sep_events, pair_v, sgn
from .layout import (
    FR_STICK,
    I_FRIC,
    I_NP,
    I_SLIDE,
    I_TIE,
    I_TORS,
    J_REL,
    J_SEP,
    P_IRB1,
    P_IRB2,
    P_MINV,
    P_MUS,
    P_RB1,
    T_BACK,
    T_S,
    T_SEP,
    T_STICK,
    T_T,
    W_F,
    W_LAMEX,
    W_N,
    W_S1M,
    W_S2M,
    W_V,
    Piece,
)


@jit_hot
def any_stuck(md, stuck):
    for j in range(md.flag[I_NP]):
        if stuck[j] != 0:
            return True
    return False


@jit
def book(md, hs, cs, dt):
    """Add ``dt`` to the time apart, on the back flank, or in stick."""
    if cs == 1:  # no flank in contact
        hs.clock[T_SEP] += dt
    elif cs == 2:  # on the back flank: contact, not contact loss
        hs.clock[T_BACK] += dt
    elif any_stuck(md, hs.stuck):
        hs.clock[T_STICK] += dt


@jit
def end_piece(md, pc, hs, te):
    """The piece ends at ``te``: book its time, move the clock and the mesh travel there."""
    v1 = md.par[P_RB1] * pc.speed
    book(md, hs, pc.cs, te - pc.t0)
    hs.clock[T_S] = pc.s0 + v1 * (te - pc.t0)
    hs.clock[T_T] = te


@jit
def settle(md, hs, act, nact, s, speed, cs):
    """`switching.settle_directions`: slip direction of slipping pairs from their velocity."""
    if md.flag[I_FRIC] != FR_STICK or cs != 0:
        return
    dirs, stuck = hs.dirs, hs.stuck
    for i in range(nact):
        j = act[i]
        if stuck[j] == 0:
            dirs[j] = sgn(pair_v(md, s, hs.y, speed, j), dirs[j])


@jit
def switch_flank(md, wk, pc, hs, label, s):
    """A separation event ``label``: the flanks part or (re)gain contact."""
    mode = hs.mode
    cs = mode[J_SEP]
    if cs == 0:      # drive flanks separate
        mode[J_SEP] = 1
        for j in range(md.flag[I_NP]):
            hs.stuck[j] = 0
    elif cs == 2:    # back flanks separate
        mode[J_SEP] = 1
    elif label == 1:  # apart -> back flank contact
        mode[J_SEP] = 2
    else:            # apart -> drive flank contact
        mode[J_SEP] = 0
        settle(md, hs, wk.active, pc.nact, s, pc.speed, mode[J_SEP])


@jit
def switch(md, wk, pc, hs, label, s):
    """`switching.switch`: apply event ``label`` (index into the event functions) at mesh
    travel s; the state ``hs.y`` is the one at the event."""
    nsep = n_sep_events(md, hs.mode[J_SEP])
    if label < nsep:
        switch_flank(md, wk, pc, hs, label, s)
        return
    pw, stuck, dirs, y = wk.pair, hs.stuck, hs.dirs, hs.y
    i = label - nsep
    j = wk.active[i]
    if stuck[j] != 0:
        evaluate(md, wk, pc, s, s, y, dirs, stuck)
        stuck[j] = 0
        dirs[j] = sgn(pw[W_LAMEX, i], 1.0)
        hs.mode[J_REL] = j + 1  # the caller records the time in clock[T_REL]
        return
    # Eq. (14) stick test with the pair tentatively stuck
    trial = wk.trial
    for jj in range(md.flag[I_NP]):
        trial[jj] = stuck[jj]
    trial[j] = 1
    evaluate(md, wk, pc, s, s, y, dirs, trial)
    lam = abs(pw[W_F, i])
    lam_e = pw[W_LAMEX, i]
    if md.flag[I_TIE] == 1:
        lam = min(lam, abs(lam_e))
    if lam <= md.par[P_MUS] * abs(pw[W_N, i]):  # the static coefficient bounds the stick
        stuck[j] = 1
        y[6 + 3] += pair_v(md, s, y, pc.speed, j)  # d v_j / d x2' = -1: v_j -> 0
    else:
        dirs[j] = sgn(lam_e, 1.0)


@jit_hot
def kinetic(par, y):
    """Kinetic energy 0.5 q'^T M q' (J)."""
    e = 0.0
    for m in range(6):
        if par[P_MINV + m] > 0.0:
            e += 0.5 * y[6 + m] * y[6 + m] / par[P_MINV + m]
    return e


@jit
def stick_impulse(md, wk, hs, i, h):
    """Keep stuck pair ``wk.active[i]`` stuck across a jump of the speed input if an
    impulse within the friction cone over ``h`` cancels its sliding velocity (applied to
    ``hs.y``, booked as friction work); else it slips. Needs `evaluate` done as slipping."""
    mp, pw, y = md.par, wk.pair, hs.y
    j = wk.active[i]
    full = md.flag[I_SLIDE] == 1
    tr = 0.0 if md.flag[I_TORS] != 0 else 1.0
    v = pw[W_V, i]
    if v == 0.0:
        return
    w2, w5 = pw[W_S1M, i] * mp[P_IRB1], pw[W_S2M, i] * mp[P_IRB2]
    # impulse along w = [-1, 0, w2, 1, 0, w5] changes v by S lambda
    if full:
        S = -(tr * (mp[P_MINV] + mp[P_MINV + 3]) + mp[P_MINV + 2] * w2 * w2
              + mp[P_MINV + 5] * w5 * w5)
    else:
        S = -(mp[P_MINV] + mp[P_MINV + 3])
    if abs(v) <= mp[P_MUS] * abs(pw[W_N, i]) * h * abs(S):
        lam = -v / S
        ke0 = kinetic(mp, y)
        y[6] -= tr * mp[P_MINV] * lam
        y[8] += mp[P_MINV + 2] * w2 * lam
        y[9] += tr * mp[P_MINV + 3] * lam
        y[11] += mp[P_MINV + 5] * w5 * lam
        y[14] += kinetic(mp, y) - ke0  # the impulse is friction work
    else:
        hs.stuck[j] = 0
        hs.dirs[j] = sgn(v, 1.0)


@jit
def speed_change(md, wk, hs, nact, torque, speed, h):
    """`switching.speed_change`: stuck pairs after a jump of the speed input (the pairs
    ``wk.active[:nact]``, drive flanks in contact)."""
    st, stuck = hs.clock, hs.stuck
    pc = Piece(st[T_T], st[T_S], torque, speed, nact, hs.mode[J_SEP])
    for i in range(nact):
        j = wk.active[i]
        if stuck[j] == 0:
            continue
        stuck[j] = 0  # evaluate as slipping: only v and the normal force are needed
        evaluate(md, wk, pc, st[T_S], st[T_S], hs.y, hs.dirs, stuck)
        stuck[j] = 1
        stick_impulse(md, wk, hs, i, h)
    settle(md, hs, wk.active, nact, st[T_S], speed, hs.mode[J_SEP])
