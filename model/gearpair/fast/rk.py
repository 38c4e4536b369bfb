"""Runge-Kutta stepping and error control (compiled): one step of an embedded explicit pair
from `tableaux` with local extrapolation and FSAL, error control in the RMS norm of
``atol + rtol * |y|``, the step bounded by ``max_step`` and ended on the stiffness table's
knots and the piece's end."""

from __future__ import annotations

import math

from ..jitcache import jit, jit_hot
from . import detmath as dm  # pow: the same bits on every CPU, not the C library's
from .contact import next_knot_dt, rhs
from .layout import (
    I_IX,
    I_METHOD,
    I_NIX,
    N_Y,
    O_NREJ,
    O_TFAIL,
    P_DX,
    P_MAXSTEP,
    P_RB1,
    P_RTOL,
    R_FSTG,
    S_COMP,
    S_KM,
    T_H,
    Step,
)
from .switching import end_piece
from .tableaux import M_DOP853, RK_A, RK_C, RK_E, RK_E3, RK_NS, RK_Q

EPS = 2.220446049250313e-16


@jit_hot
def stage(meth, stg, y, K, hh, ytmp):
    """ytmp = y + hh sum_j a[stg, j] K[j] (zero couplings skipped: DOP853 has many)."""
    for m in range(N_Y):
        ytmp[m] = 0.0
    for j in range(stg):
        a = RK_A[meth, stg, j]
        if a != 0.0:
            for m in range(N_Y):
                ytmp[m] += a * K[j, m]
    for m in range(N_Y):
        ytmp[m] = y[m] + hh * ytmp[m]


@jit_hot
def err_norm(md, yold, ynew, K, hh):
    """Weighted RMS norm of the local error estimate (DOP853: Hairer's blend of its 5th- and
    3rd-order estimates, which keeps the step from growing where the 5th-order one vanishes
    by chance).

    The mean is over all N_Y components, the held ones contributing their exact zero: the
    step sequence does not depend on whether a component whose rate vanishes is integrated
    (friction off steps as friction with mu = 0)."""
    mi, atol, rtol = md.flag, md.atol, md.par[P_RTOL]
    meth = mi[I_METHOD]
    ns = RK_NS[meth]
    blend = meth == M_DOP853  # DP5 has no 3rd-order estimate
    a5 = 0.0
    a3 = 0.0
    for k in range(mi[I_NIX]):
        m = mi[I_IX + k]
        sk = atol[m] + rtol * max(abs(yold[m]), abs(ynew[m]))
        e5 = 0.0
        e3 = 0.0
        for j in range(ns):
            e5 += RK_E[meth, j] * K[j, m]
            if blend:
                e3 += RK_E3[meth, j] * K[j, m]
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
def initial_step(md, wk, pc, hs, f0, t_lim):
    """Starting step from the size of y, y' and y'' (Hairer, Norsett & Wanner, II.4)."""
    mp, atol, y, ytmp, ftmp = md.par, md.atol, hs.y, wk.ytmp, wk.ynew
    t0 = pc.t0
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
    s_idx = pc.s0 + mp[P_RB1] * pc.speed * 0.5 * h0
    rhs(md, wk, pc, hs, t0 + h0, s_idx, ytmp, ftmp)
    d2 = 0.0
    for m in range(N_Y):
        sk = atol[m] + rtol * abs(y[m])
        d2 += ((ftmp[m] - f0[m]) / sk) ** 2
    d2 = math.sqrt(d2 / N_Y) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = dm.pow(0.01 / max(d1, d2), 1.0 / RK_Q[md.flag[I_METHOD]])
    return min(100.0 * h0, h1, mp[P_MAXSTEP])


@jit_hot
def first_step(md, wk, pc, hs, tb):
    """Start the steps of a piece: the first stage at its start, the step size (the last
    one, else `initial_step`) and the next knot. Returns (h, t_knot)."""
    y, K, t = hs.y, wk.stages, pc.t0
    v1 = md.par[P_RB1] * pc.speed
    t_knot = t + next_knot_dt(md, pc.s0, pc.speed, wk.active, pc.nact)
    h = hs.clock[T_H]
    hguess = h if h > 0.0 else 1e-7
    s_idx = pc.s0 + v1 * 0.5 * min(hguess, t_knot - t, tb - t)
    rhs(md, wk, pc, hs, pc.t0, s_idx, y, K[0])
    wk.dense[R_FSTG, 0] = wk.scal[S_KM] * wk.scal[S_COMP]
    if not (h > 0.0):
        h = initial_step(md, wk, pc, hs, K[0], min(tb, t_knot))
    for m in range(N_Y):  # held components: y's values, which `interp` leaves in place
        wk.ytmp[m] = y[m]
    return h, t_knot


@jit_hot
def step_error(md, wk, pc, hs, sp):
    """The stages of step ``sp`` (the new point into ``wk.ynew``) and its error norm."""
    meth = md.flag[I_METHOD]
    y, K, ytmp, hh, t = hs.y, wk.stages, wk.ytmp, sp.hh, sp.t
    for stg in range(1, RK_NS[meth]):
        stage(meth, stg, y, K, hh, ytmp)
        c = RK_C[meth, stg]
        ts = sp.tn if c == 1.0 else t + c * hh
        rhs(md, wk, pc, hs, ts, sp.si, ytmp, K[stg])
        # the mesh force at the stage: its Runge-Kutta quadrature is the force's integral
        # over the step at the method's order (a quadrature component of y, without one: it
        # feeds nothing back and takes no part in the error control)
        wk.dense[R_FSTG, stg] = wk.scal[S_KM] * wk.scal[S_COMP]
    for m in range(N_Y):
        wk.ynew[m] = ytmp[m]
    err = err_norm(md, y, wk.ynew, K, hh)
    if not math.isfinite(err):
        err = 1e10
    return err


@jit_hot
def next_h(md, err, h, sp, rejected):
    """Step size after an attempt with error norm ``err`` (accepted if err <= 1)."""
    expo = -1.0 / RK_Q[md.flag[I_METHOD]]
    # Safety factor 0.8, not the usual 0.9: at 0.9 a fifth of all attempts were
    # rejected, most likely because the local error of the lightly damped mesh
    # ringing varies with its phase from step to step. 0.8 halves the rejections,
    # and the error at a given rtol falls by 1.5-2.5 x while the cost stays equal or
    # falls by up to 6 % (interleaved A/B). 0.7 costs more at tight rtol.
    hh = sp.hh
    if err <= 1.0:
        fac = 10.0 if err == 0.0 else min(10.0, 0.8 * dm.pow(err, expo))
        if rejected:
            fac = min(1.0, fac)
        if (sp.last or sp.at_knot) and hh < h:
            if fac < 1.0:  # a truncated step keeps the step size it was cut from
                h = hh * fac
        else:
            h = hh * fac
        return h
    return hh * max(0.2, 0.8 * dm.pow(err, expo))


@jit_hot
def plan_step(md, pc, t, h, t_knot, tb):
    """The next step from t: size, end, and whether it ends the piece or on a knot."""
    v1 = md.par[P_RB1] * pc.speed
    hh = min(h, md.par[P_MAXSTEP])
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
    si = pc.s0 + v1 * (t + 0.5 * hh - pc.t0)
    tn = lim if (last or at_knot) else t + hh
    return Step(t, hh, tn, si, last, at_knot)


@jit_hot
def try_step(md, wk, pc, hs, t, h, t_knot, tb):
    """Attempt steps from t until one passes the error test.

    Returns (status, h, t_knot, step): status 1 with the accepted step, 0 if the piece
    ended at ``tb`` (a rounding error away), -1 on a step-size underflow.
    """
    v1 = md.par[P_RB1] * pc.speed
    rejected = False
    while True:
        sp = plan_step(md, pc, t, h, t_knot, tb)
        hh = sp.hh
        if hh <= 16.0 * EPS * max(abs(t), 1e-300) or not (hh > 0.0):
            if sp.at_knot and hh >= 0.0:  # rounding: the knot is already here
                t_knot = t + next_knot_dt(md, pc.s0 + v1 * (t - pc.t0) + 1e-6 * md.par[P_DX]
                                          * (1.0 if pc.speed > 0 else -1.0), pc.speed,
                                          wk.active, pc.nact)
                continue
            if sp.last and hh >= 0.0:
                # A boundary a rounding error away from the end of the step (a
                # communication point on a pair entry): nothing is left to integrate.
                end_piece(md, pc, hs, tb)
                return 0, h, t_knot, sp
            wk.summary[O_TFAIL] = t
            return -1, h, t_knot, sp
        err = step_error(md, wk, pc, hs, sp)
        h = next_h(md, err, h, sp, rejected)
        if err <= 1.0:
            return 1, h, t_knot, sp
        rejected = True
        wk.summary[O_NREJ] += 1.0
