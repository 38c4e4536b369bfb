"""Extremes of the mesh force between the points where it is evaluated (compiled).

`StepSummary.mesh_force_min` and ``mesh_force_max`` are the extremes of the trajectory, not
of samples: the force at step ends, switches and segment boundaries is recorded as it is,
and in between a step (a Runge-Kutta step or an exact-propagator stretch) is modelled from
its own end values and time derivatives: a cubic Hermite from F and dF/dt for a Runge-Kutta
step, a quintic from F, F' and F'' for an exact stretch (whose A gives F'' for free). Only
when that model's reach could beat the running least or greatest value are its turning
points sought; a Runge-Kutta step's are then taken from the quintic Hermite of F, F', F''
(F'' from its stage rates) where that is accurate to max(rtol, 1e-6), else refined on the
method's continuous extension (a Newton step on a three-point parabola). Most steps cost a
few flops, and the extremes do not depend on where steps end (the output interval), to
integration accuracy.
"""

from __future__ import annotations

import math

from ..jitcache import jit, jit_hot
from .contact import dte_of, flank_compression, pair_k, pair_k_and_slope, pair_xi, table_index
from .events import extend, interp, record_force
from .layout import (
    I_KIND,
    I_METHOD,
    KIND_CUBIC,
    NZ,
    O_FMAX,
    O_FMIN,
    P_RB1,
    P_RTOL,
    R_FSTG,
    S_COMP,
    S_DDELTA,
    S_KM,
    S_QDD,
    W_DK,
)
from .tableaux import RK_NS

# How far a Hermite interpolant strays from its end values, per unit of its end terms:
# theta (1 - theta)^2 <= 4/27 (cubic slope basis); quintic: theta (1 - theta)^3 (1 + 3 theta)
# <= 0.198 (slope) and theta^2 (1 - theta)^3 / 2 <= 0.0173 (curvature)
CUBIC_REACH = 4.0 / 27.0
QUINTIC_REACH_1 = 0.2
QUINTIC_REACH_2 = 0.018
ETA = 1e-3  # half-width (fraction of the step) of the parabola of a Newton refinement


@jit_hot
def could_beat(summ, f0, f1, reach):
    """Whether a step whose force stays within ``reach`` (N) of its end values f0, f1 could
    set a new least or greatest value (the running ones in ``summ``)."""
    return max(f0, f1) + reach > summ[O_FMAX] or min(f0, f1) - reach < summ[O_FMIN]


@jit_hot
def cubic_turns(f0, d0, f1, d1, h):
    """Turning points in (0, 1) of the cubic Hermite p(theta) (p(0) = f0, p(1) = f1,
    p'(0) = h d0, p'(1) = h d1); nan where there is none. Returns (r1, r2, c, d) with
    p = f0 + h d0 theta + c theta^2 + d theta^3."""
    b = h * d0
    c = 3.0 * (f1 - f0) - h * (2.0 * d0 + d1)
    d = 2.0 * (f0 - f1) + h * (d0 + d1)
    r1 = math.nan
    r2 = math.nan
    if abs(d) <= 1e-12 * (abs(b) + abs(c)):  # p' = b + 2 c theta
        if c != 0.0:
            r1 = -b / (2.0 * c)
    else:  # p' = b + 2 c theta + 3 d theta^2, roots without cancellation
        disc = c * c - 3.0 * d * b
        if disc >= 0.0:
            q = -(c + math.copysign(math.sqrt(disc), c))
            r1 = q / (3.0 * d)
            if q != 0.0:
                r2 = b / q
    if not (0.0 < r1 < 1.0):
        r1 = math.nan
    if not (0.0 < r2 < 1.0):
        r2 = math.nan
    return r1, r2, c, d


@jit_hot
def compression(md, pc, y):
    """Mesh compression (m) at state y: delta on the drive flank, delta + b on the back
    flank (the mesh force is km times it; apart it is not used)."""
    return flank_compression(md.par, dte_of(y), pc.cs)


@jit_hot
def force_at(md, wk, pc, t, s_idx, yk):
    """Elastic mesh force km * compression (N) at (t, yk) on the stiffness-table interval of
    ``s_idx`` (a step's, as its stages use)."""
    if pc.cs == 1:
        return 0.0
    mp = md.par
    s = pc.s0 + mp[P_RB1] * pc.speed * (t - pc.t0)
    km = 0.0
    for i in range(pc.nact):
        xi = pair_xi(mp, s, wk.active[i])
        km += pair_k(md, xi, xi + (s_idx - s), pc.nact)
    return km * compression(md, pc, yk)


@jit_hot
def stiffness_rates(md, wk, pc, t, s_idx, curvature):
    """(v1, km, d km/ds, d2 km/ds2) of the active pairs at time t (m/s, N/m, N/m^2, N/m^3),
    on the table interval of ``s_idx``; the curvature only when ``curvature`` (else 0)."""
    mp = md.par
    v1 = mp[P_RB1] * pc.speed
    s = pc.s0 + v1 * (t - pc.t0)
    km = 0.0
    dkm = 0.0
    d2km = 0.0
    cubic = curvature and md.flag[I_KIND] == KIND_CUBIC
    for i in range(pc.nact):
        xi = pair_xi(mp, s, wk.active[i])
        xi_idx = xi + (s_idx - s)
        k, dk = pair_k_and_slope(md, xi, xi_idx, pc.nact)
        km += k
        dkm += dk
        if cubic:
            j = table_index(md, xi_idx)
            c = 4 * j
            d2km += 6.0 * md.k_coef[c + 3] * (xi - md.xi_knots[j]) + 2.0 * md.k_coef[c + 2]
    return v1, km, dkm, d2km


@jit
def force_rate(md, wk, pc, t, s_idx, y):
    """dF/dt (N/s) of the elastic mesh force at (t, y): d km/dt compression + km delta'
    (the stiffness on the table interval of ``s_idx``)."""
    if pc.cs == 1:
        return 0.0
    v1, km, dkm, _ = stiffness_rates(md, wk, pc, t, s_idx, False)
    return dkm * v1 * compression(md, pc, y) + km * (y[7] - y[10] + y[8] + y[11])


@jit_hot
def force_rate_evaluated(md, wk, pc):
    """dF/dt (N/s) at the point ``wk`` was last evaluated at (a step's last stage: its end)."""
    if pc.cs == 1:
        return 0.0
    sc = wk.scal
    dkm = 0.0
    for i in range(pc.nact):
        dkm += wk.pair[W_DK, i]
    return dkm * md.par[P_RB1] * pc.speed * sc[S_COMP] + sc[S_KM] * sc[S_DDELTA]


@jit_hot
def extension_force(md, wk, pc, sp, nf, th):
    """The mesh force at fraction ``th`` of step ``sp`` on its continuous extension."""
    interp(md, wk.dense, nf, th, wk.ytmp)
    return force_at(md, wk, pc, sp.t + th * sp.hh, sp.si, wk.ytmp)


@jit
def refine_turn(md, wk, pc, sp, nf, th, th_lim, sgn):
    """A Newton step towards the turning point near ``th`` (sgn 1: a maximum, -1: a
    minimum) of the force on the step's continuous extension, from a parabola through three
    values ETA apart, and the value there; every value seen is a point of the trajectory
    and is recorded. From the cubic's turn one step leaves the value off by a few ulp."""
    summ = wk.summary
    if th_lim > 2.0 * ETA:
        tc = min(max(th, ETA), th_lim - ETA)
        fm = extension_force(md, wk, pc, sp, nf, tc - ETA)
        fc = extension_force(md, wk, pc, sp, nf, tc)
        fp = extension_force(md, wk, pc, sp, nf, tc + ETA)
        record_force(summ, fm)
        record_force(summ, fc)
        record_force(summ, fp)
        curv = fp - 2.0 * fc + fm
        if not (sgn * curv < 0.0):
            return
        step = min(max(-ETA * (fp - fm) / (2.0 * curv), -0.25), 0.25)
        th = min(max(tc + step, 0.0), th_lim)
        if abs(step) < 1e-6:
            return
    record_force(summ, extension_force(md, wk, pc, sp, nf, th))


@jit
def force_curvature(md, wk, pc, t, s_idx, y, yd):
    """d2F/dt2 (N/s^2) of the elastic mesh force at (t, y) with y' = yd: km'' compression
    + 2 km' delta' + km delta'' (the stiffness on the table interval of ``s_idx``)."""
    if pc.cs == 1:
        return 0.0
    v1, km, dkm, d2km = stiffness_rates(md, wk, pc, t, s_idx, True)
    comp = compression(md, pc, y)
    return (d2km * v1 * v1 * comp + 2.0 * dkm * v1 * (y[7] - y[10] + y[8] + y[11])
            + km * (yd[7] - yd[10] + yd[8] + yd[11]))


@jit
def refine_turns(md, wk, pc, hs, sp, scan, turns, ends):
    """`refine_turn` for the turning points ``turns`` (theta, sgn; theta nan: none);
    ``scan``: (rows of the step's continuous extension, fraction of the step before a switch).

    A whole step the scan did not extend (``hs.y`` and ``wk.ynew`` its ends, the first and
    last stages their rates) first tries the quintic Hermite of F, F', F'' at its ends
    (F'' from the stage rates and the table's curvature): where its error, estimated as its
    difference to the cubic times (omega h)^2 / 120 (omega from F''/F' at the ends), is
    below max(rtol, 1e-6) of the force, its turn is taken; otherwise the continuous
    extension is built (DOP853: three more stages; always building it cost 8-11 % of a
    stick-slip run advanced every 1e-4 or 1e-3 s, the quintic brings that to 1-4 %)."""
    f0, d0, f1, d1 = ends
    nf, th_lim = scan
    h = sp.hh
    quick = nf <= 3 and th_lim >= 1.0
    e0 = e1 = wh = tol = c = d = 0.0
    if quick:
        ns = RK_NS[md.flag[I_METHOD]]
        e0 = force_curvature(md, wk, pc, sp.t, sp.si, hs.y, wk.stages[0])
        e1 = force_curvature(md, wk, pc, sp.tn, sp.si, wk.ynew, wk.stages[ns - 1])
        wh = h * max(abs(e0), abs(e1)) / max(abs(d0), abs(d1), 1e-300)
        tol = max(md.par[P_RTOL], 1e-6) * max(abs(f0), abs(f1))
        c = 3.0 * (f1 - f0) - h * (2.0 * d0 + d1)
        d = 2.0 * (f0 - f1) + h * (d0 + d1)
    for k in range(2):
        th, sgn = turns[k]
        if not (th > 0.0):
            continue
        if quick:
            for _it in range(4):
                _p, p1, p2 = quintic(f0, d0, e0, f1, d1, e1, h, th)
                if p2 == 0.0:
                    break
                step = p1 / p2
                th = min(max(th - step, 0.0), 1.0)
                if abs(step) < 1e-6:
                    break
            q = quintic(f0, d0, e0, f1, d1, e1, h, th)[0]
            p3 = f0 + th * (h * d0 + th * (c + th * d))
            if abs(q - p3) * wh * wh / 120.0 <= tol:
                record_force(wk.summary, q)
                continue
            quick = False
        if nf <= 3:  # none or the cheap Hermite of the state (DOP853's scan)
            nf = extend(md, wk, pc, hs, sp)
        refine_turn(md, wk, pc, sp, nf, th, th_lim, sgn)


@jit_hot
def step_ends(md, wk, pc, hs, sp, d0):
    """(F, dF/dt) at the start and the end of the accepted step ``sp`` (N, N/s), right
    after its stages (the last one is its end); ``d0``: the start's rate if known (the end
    of the step before, unless a stiffness-table knot lies between), else nan."""
    if not (d0 == d0):
        d0 = force_rate(md, wk, pc, sp.t, sp.si, hs.y)
    fs = wk.dense[R_FSTG]
    return fs[0], d0, fs[RK_NS[md.flag[I_METHOD]] - 1], force_rate_evaluated(md, wk, pc)


@jit_hot
def step_extremes(md, wk, pc, hs, sp, nf, ends, th_lim):
    """Interior extremes of the mesh force over the accepted Runge-Kutta step ``sp`` up to
    the fraction ``th_lim`` of it (a located switch), into the running least and greatest
    values of ``wk.summary`` (the step's end values are the scan's).

    ``ends``: `step_ends`; ``nf``: rows of the step's continuous extension in ``wk.dense``.
    The turning points of the cubic Hermite of F are refined on the extension only when they
    could beat a running value.
    """
    f0, d0, f1, d1 = ends
    summ = wk.summary
    h = sp.hh
    reach = CUBIC_REACH * h * (abs(d0) + abs(d1))
    if pc.cs == 1 or not could_beat(summ, f0, f1, reach):
        return
    r1, r2, c, d = cubic_turns(f0, d0, f1, d1, h)
    margin = 0.01 * reach  # the cubic's own error: refine a turn this close to a record
    t1 = (math.nan, 0.0)
    t2 = (math.nan, 0.0)
    for k in range(2):
        r = r1 if k == 0 else r2
        if not (r < th_lim):  # nan: none
            continue
        p = f0 + r * (h * d0 + r * (c + r * d))
        sgn = -1.0 if 2.0 * c + 6.0 * d * r > 0.0 else 1.0
        if (p + margin > summ[O_FMAX]) if sgn > 0.0 else (p - margin < summ[O_FMIN]):
            if k == 0:
                t1 = (r, sgn)
            else:
                t2 = (r, sgn)
    if t1[0] > 0.0 or t2[0] > 0.0:
        refine_turns(md, wk, pc, hs, sp, (nf, th_lim), (t1, t2), ends)


@jit_hot
def quintic(f0, d0, e0, f1, d1, e1, h, th):
    """The quintic Hermite of (F, F', F'') at both ends of a stretch of h seconds, at
    fraction th: its value and first two derivatives in th."""
    t2 = th * th
    t3 = t2 * th
    t4 = t3 * th
    t5 = t4 * th
    df = f0 - f1
    a0, a1 = h * d0, h * d1
    b0, b1 = h * h * e0, h * h * e1
    p = (f1 + df * (1.0 - 10.0 * t3 + 15.0 * t4 - 6.0 * t5)
         + a0 * (th - 6.0 * t3 + 8.0 * t4 - 3.0 * t5) + a1 * (-4.0 * t3 + 7.0 * t4 - 3.0 * t5)
         + b0 * 0.5 * (t2 - 3.0 * t3 + 3.0 * t4 - t5) + b1 * 0.5 * (t3 - 2.0 * t4 + t5))
    p1 = (df * (-30.0 * t2 + 60.0 * t3 - 30.0 * t4)
          + a0 * (1.0 - 18.0 * t2 + 32.0 * t3 - 15.0 * t4)
          + a1 * (-12.0 * t2 + 28.0 * t3 - 15.0 * t4)
          + b0 * 0.5 * (2.0 * th - 9.0 * t2 + 12.0 * t3 - 5.0 * t4)
          + b1 * 0.5 * (3.0 * t2 - 8.0 * t3 + 5.0 * t4))
    p2 = (df * (-60.0 * th + 180.0 * t2 - 120.0 * t3)
          + a0 * (-36.0 * th + 96.0 * t2 - 60.0 * t3)
          + a1 * (-24.0 * th + 84.0 * t2 - 60.0 * t3)
          + b0 * 0.5 * (2.0 - 18.0 * th + 36.0 * t2 - 20.0 * t3)
          + b1 * 0.5 * (6.0 * th - 24.0 * t2 + 20.0 * t3))
    return p, p1, p2


@jit_hot
def exact_terms(md, A, z, km, cs):
    """(F, F', F'') (N, N/s, N/s^2) of an exact stretch at z (z' = A z; F'' = km g . q''
    from the rows of A z, as `lti.lti_dd`)."""
    if cs == 1:
        return 0.0, 0.0, 0.0
    comp = flank_compression(md.par, dte_of(z), cs)
    dd = 0.0
    for m in range(NZ):
        dd += (A[7, m] - A[10, m] + A[8, m] + A[11, m]) * z[m]
    return km * comp, km * (z[7] - z[10] + z[8] + z[11]), km * dd


@jit_hot
def evaluated_terms(wk, cs):
    """`exact_terms` at the point ``wk`` was last evaluated at (constant stiffness: F' and
    F'' are km delta' and km g . q'', already in hand)."""
    sc = wk.scal
    if cs == 1:
        return 0.0, 0.0, 0.0
    km = sc[S_KM]
    return km * sc[S_COMP], km * sc[S_DDELTA], km * (sc[S_QDD + 1] - sc[S_QDD + 4]
                                                     + sc[S_QDD + 2] + sc[S_QDD + 5])


@jit
def stretch_turns(summ, a, b, h, reach):
    """Record the values at the turning points of the quintic Hermite of ``a`` = (F, F',
    F'') at the start and ``b`` at the end of a stretch of h seconds: Newton on its slope
    from the turns of the cubic of F and F', for the turns whose cubic value comes within
    a hundredth of ``reach`` (far more than the cubic's error at the sample spacing) of a
    new least or greatest value."""
    f0, d0, e0 = a
    f1, d1, e1 = b
    r1, r2, c, d = cubic_turns(f0, d0, f1, d1, h)
    margin = 0.01 * reach
    for k in range(2):
        th = r1 if k == 0 else r2
        if not (th > 0.0):  # nan: none
            continue
        p = f0 + th * (h * d0 + th * (c + th * d))
        if p + margin <= summ[O_FMAX] and p - margin >= summ[O_FMIN]:
            continue
        for _it in range(4):
            _p, p1, p2 = quintic(f0, d0, e0, f1, d1, e1, h, th)
            if p2 == 0.0:
                break
            step = p1 / p2
            th = min(max(th - step, 0.0), 1.0)
            if abs(step) < 1e-6:  # the value is then off by (1e-6 h)^2 F''/2 at most
                break
        record_force(summ, quintic(f0, d0, e0, f1, d1, e1, h, th)[0])


@jit_hot
def stretch_extremes(summ, a, b, h):
    """Interior extremes of the mesh force over an exact stretch of h seconds into the
    running least and greatest values ``summ`` (`Work.summary`), from ``a`` and ``b``, the
    (F, F', F'') at its ends (`exact_terms`): the turning points of their quintic Hermite
    (error O(h^6), about 1e-8 of the force's swing at the sample spacing), sought only when
    its reach could beat a running value. The end values are recorded by the caller."""
    reach = h * (QUINTIC_REACH_1 * (abs(a[1]) + abs(b[1]))
                 + QUINTIC_REACH_2 * h * (abs(a[2]) + abs(b[2])))
    if h > 0.0 and could_beat(summ, a[0], b[0], reach):
        stretch_turns(summ, a, b, h, reach)
