"""The exact propagator for constant-coefficient pieces (compiled).

With friction off and constant or rectangular stiffness, a piece (one contact state, one pair
set, inputs held) is the linear time-invariant system z' = A z with
z = [q, q', a, a', torque, 1, integral of u2]: the torque and the constant are states with
zero rate so that A does not depend on the inputs. Then z(t + h) = expm(A h) z(t) exactly:
the 2.7-4 kHz ringing that an explicit method must resolve step by step costs nothing.
"""

from __future__ import annotations

import math

import numpy as np

from ..jitcache import jit, jit_hot
from .contact import dte_of, flank_compression, n_events, pair_k, pair_xi, rhs, solve_small
from .detlinalg import balance_n
from .events import (
    dte_noise,
    events_at,
    falls,
    flank_guard,
    illinois,
    illinois_point,
    mark_missed,
    record_force,
    start_flanks,
)
from .extremes import evaluated_terms, exact_terms, stretch_extremes
from .layout import (
    I_TORS,
    J_REL,
    L_NSLOT,
    L_SCRATCH,
    N_Y,
    NZ,
    O_FINT,
    O_NSTEPS,
    P_C,
    P_IRB1,
    P_KB,
    P_MINV,
    P_RTOL,
    P_SPACING,
    P_TTOL,
    STATUS_OK,
    T_S,
    T_T,
    Y_A,
    Y_AD,
    Z_A,
    Z_AD,
    Z_IU2,
    Z_ONE,
    Z_TQ,
    LtiPiece,
    Piece,
)
from .rk import EPS
from .switching import end_piece, switch
from .views import array_at, dims, word

PADE6 = np.array([math.factorial(12 - k) * math.factorial(6)
                  / (math.factorial(12) * math.factorial(k) * math.factorial(6 - k))
                  for k in range(7)])
G_DTE = (0.0, 1.0, 1.0, 0.0, -1.0, 1.0)  # d delta / d q


@jit_hot
def matmul(A, B, C):
    """C = A B (NZ x NZ)."""
    for i in range(NZ):
        for j in range(NZ):
            C[i, j] = 0.0
        for k in range(NZ):
            a = A[i, k]
            if a != 0.0:
                for j in range(NZ):
                    C[i, j] += a * B[k, j]


@jit_hot
def matvec(P, z, out):
    for i in range(NZ):
        acc = 0.0
        for j in range(NZ):
            acc += P[i, j] * z[j]
        out[i] = acc


@jit
def balance(X, d):
    """X <- D^-1 X D with D = diag(d), powers of two (LAPACK gebal without permutations)."""
    balance_n(X, NZ, d)


@jit
def scale_down(X):
    """Halve X until its 1-norm is at most 0.5; returns the number of halvings."""
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
    return sq


@jit
def pade66(X, E, S):
    """E = the diagonal Pade (6, 6) approximant of expm(X); S: scratch as in `expm`."""
    X2, X4, X6, U, V, T = S[1], S[2], S[3], S[4], S[5], S[6]
    matmul(X, X, X2)
    matmul(X2, X2, X4)
    matmul(X4, X2, X6)
    c = PADE6
    for i in range(NZ):
        for j in range(NZ):
            T[i, j] = c[3] * X2[i, j] + c[5] * X4[i, j]
            V[i, j] = c[2] * X2[i, j] + c[4] * X4[i, j] + c[6] * X6[i, j]
        T[i, i] += c[1]
        V[i, i] += c[0]
    matmul(X, T, U)
    for i in range(NZ):
        for j in range(NZ):
            E[i, j] = V[i, j] + U[i, j]   # numerator
            V[i, j] = V[i, j] - U[i, j]   # denominator
    # solve V R = E (partial pivoting), R into E
    # S[10:12] as one matrix (a reshape would call numba's runtime library)
    Wd = array_at(word(S[10], 0), dims(NZ, 2 * NZ), 0.0)
    for i in range(NZ):
        for j in range(NZ):
            Wd[i, j] = V[i, j]
            Wd[i, NZ + j] = E[i, j]
    solve_small(Wd, Wd.shape[0], Wd.shape[0])
    for i in range(NZ):
        for j in range(NZ):
            E[i, j] = Wd[i, NZ + j]


@jit
def expm(A, h, E, S):
    """E = expm(A h): power-of-two balancing, scaling and squaring, diagonal Pade (6, 6)
    (truncation error below 1e-19 at the scaled norm 0.5). ``S``: scratch (12 matrices; 8
    and 9 are left alone for the caller)."""
    X, T = S[0], S[6]
    d = S[7][0]
    for i in range(NZ):
        for j in range(NZ):
            X[i, j] = A[i, j] * h
    balance(X, d)
    sq = scale_down(X)
    pade66(X, E, S)
    for _ in range(sq):
        matmul(E, E, T)
        for i in range(NZ):
            for j in range(NZ):
                E[i, j] = T[i, j]
    for i in range(NZ):
        for j in range(NZ):
            E[i, j] *= d[i] / d[j]


@jit_hot
def z_to_y(z, y):
    for m in range(12):
        y[m] = z[m]
    y[Y_A] = z[Z_A]
    y[Y_AD] = z[Z_AD]


@jit
def probe_column(md, wk, pc, hs, c, A):
    """Column c of A: the right-hand side at the unit vector of z-component c (c = Z_ONE:
    at z = 0 with the constant 1, the affine part) minus the affine part."""
    ytmp, dy = wk.ytmp, wk.lti_vecs[5]
    for m in range(N_Y):
        ytmp[m] = 0.0
    tq = 0.0
    if c < 12:
        ytmp[c] = 1.0
    elif c == Z_A:
        ytmp[Y_A] = 1.0
    elif c == Z_AD:
        ytmp[Y_AD] = 1.0
    elif c == Z_TQ:
        tq = 1.0
    rhs(md, wk, Piece(pc.t0, pc.s0, tq, pc.speed, pc.nact, pc.cs), hs, pc.t0, pc.s0, ytmp, dy)
    if c == Z_ONE:
        for r in range(12):
            A[r, Z_ONE] = dy[r]
        A[Z_A, Z_ONE] = dy[Y_A]
        return
    for r in range(12):
        A[r, c] = dy[r] - A[r, Z_ONE]
    A[Z_A, c] = dy[Y_A] - A[Z_A, Z_ONE]


@jit
def lti_matrix(md, wk, pc, hs, A):
    """A of the piece by probing the (affine) right-hand side: the same physics as the
    Runge-Kutta path, column by column."""
    for i in range(NZ):
        for j in range(NZ):
            A[i, j] = 0.0
    for k in range(-1, Z_ONE):  # the affine part (column Z_ONE) first
        probe_column(md, wk, pc, hs, Z_ONE if k < 0 else k, A)
    A[Z_IU2, 5] = 1.0


@jit
def lti_slot(md, wk, pc, hs, km, h):
    """Index of the cached propagator for (cs, km, h); built on a miss (least recently
    used slot). Keys match exactly: what a step computes must not depend on what the cache
    saw before (a state restored into a fresh engine continues bit for bit). A grid's
    round-off makes only a few distinct step lengths, which the slots hold."""
    Lm, Lk, cs = wk.lti_mats, wk.lti_keys, pc.cs
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
        lti_matrix(md, wk, pc, hs, Lm[k_new])
    expm(Lm[k_new], h, Lm[L_NSLOT + k_new], Lm[L_SCRATCH:])
    Lk[k_new, 0], Lk[k_new, 1], Lk[k_new, 2], Lk[k_new, 3] = cs, km, h, use
    return k_new


@jit_hot
def free_index(nf, a):
    """The coordinate of free coordinate a: u1, u2 (torsional) or all six."""
    return (2, 5)[a] if nf == 2 else a


@jit
def static_solve(md, A, z, W, nf):
    """Into W: the stiffness K of the free coordinates (from A), Cholesky-factored in place,
    with K^-1 (static force) and K^-1 g in columns nf and nf + 1. Returns False unless K is
    positive definite."""
    mp = md.par
    for a in range(nf):
        ia = free_index(nf, a)
        for b in range(nf):
            W[a, b] = -A[6 + ia, free_index(nf, b)] / mp[P_MINV + ia]
        # static force: a, torque and the constant at q = q' = 0
        W[a, nf] = (A[6 + ia, Z_A] * z[Z_A] + A[6 + ia, Z_TQ] * z[Z_TQ]
                    + A[6 + ia, Z_ONE]) / mp[P_MINV + ia]
        W[a, nf + 1] = G_DTE[ia]
    for j in range(nf):  # Cholesky K = L L^T in place (lower)
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
    return True


@jit
def lti_quiet(md, A, z, cs, W):
    """True when the piece provably stays in its contact state with the mesh force within
    rtol of its static value: then it needs no sampling for events or the peak force.

    The deviation e from the static equilibrium of a passive system with constant
    coefficients has non-increasing energy E = e'^T M e' / 2 + e^T K e / 2, so
    |g . e| <= sqrt(2 E g^T K^-1 g) for the whole piece. Needs K positive definite (in mesh)
    and a load-shaft end at rest (a' = 0).
    """
    mp = md.par
    if cs == 1 or z[Z_AD] != 0.0:
        return False
    nf = 2 if md.flag[I_TORS] != 0 else 6
    if not static_solve(md, A, z, W, nf):
        return False
    # W[:, nf] = q_p (free part), W[:, nf + 1] = K^-1 g
    gkg = 0.0
    comp_p = 0.0
    energy = 0.0
    for a in range(nf):
        ia = free_index(nf, a)
        ga = G_DTE[ia]
        gkg += ga * W[a, nf + 1]
        comp_p += ga * W[a, nf]
        energy += 0.5 * z[6 + ia] * z[6 + ia] / mp[P_MINV + ia]
    comp_p = flank_compression(mp, comp_p, cs)
    # e^T K e from K = -M A (rows of the free coordinates), e = q - q_p
    for a in range(nf):
        ia = free_index(nf, a)
        ka = 0.0
        for b in range(nf):
            ib = free_index(nf, b)
            ka += -A[6 + ia, ib] / mp[P_MINV + ia] * (z[ib] - W[b, nf])
        energy += 0.5 * (z[ia] - W[a, nf]) * ka
    bound = math.sqrt(max(2.0 * energy * gkg, 0.0))
    if cs == 0:
        return comp_p > 0.0 and bound <= mp[P_RTOL] * comp_p
    return comp_p < 0.0 and bound <= -mp[P_RTOL] * comp_p


@jit_hot
def comp_of(par, z, cs):
    if cs == 1:
        return 0.0
    return flank_compression(par, dte_of(z), cs)


@jit_hot
def stored_change(par, z0, z1, km, cs):
    """Stored energy at z1 minus at z0 (J): kinetic, supports, load shaft, mesh spring (as
    `energy`), each as k (x1 - x0)(x1 + x0) / 2 so that a small change of a large stored
    energy keeps its relative accuracy."""
    de = 0.0
    for m in range(6):
        if par[P_MINV + m] > 0.0:
            de += 0.5 / par[P_MINV + m] * (z1[6 + m] - z0[6 + m]) * (z1[6 + m] + z0[6 + m])
        de += 0.5 * par[P_KB + m] * (z1[m] - z0[m]) * (z1[m] + z0[m])
    # load shaft: kr2 (u2 - a)^2 / 2 replaces the kr2 u2^2 / 2 counted above
    e0, e1 = z0[5] - z0[Z_A], z1[5] - z1[Z_A]
    de += 0.5 * par[P_KB + 5] * ((e1 - e0) * (e1 + e0) - (z1[5] - z0[5]) * (z1[5] + z0[5]))
    c0, c1 = comp_of(par, z0, cs), comp_of(par, z1, cs)
    return de + 0.5 * km * (c1 - c0) * (c1 + c0)


@jit
def lti_finish(par, y, z0, z1, dt, km, cs):
    """State z1 into y, with the input work and the damping loss of the stretch from z0:
    input = torque/rb1 du1 - a' (kr2 int(u2 - a) + cr2 int(u2' - a')). No friction or
    parametric power acts here, so the damping loss is the input work minus the change of
    stored energy (exact for the exact solution; a negative rounding residue is dropped, the
    loss of a passive damper cannot be)."""
    tq, ad = z0[Z_TQ], z0[Z_AD]
    int_a = z0[Z_A] * dt + 0.5 * ad * dt * dt
    w_in = tq * par[P_IRB1] * (z1[2] - z0[2]) - ad * (
        par[P_KB + 5] * (z1[Z_IU2] - z0[Z_IU2] - int_a) + par[P_C + 5] * (z1[5] - z0[5] - ad * dt))
    y[12] += w_in
    y[13] += max(w_in - stored_change(par, z0, z1, km, cs), 0.0)
    z_to_y(z1, y)


@jit_hot
def lti_dd(A, z):
    """delta'' = g . q'' of the exact solution at z (rows of A z)."""
    acc = 0.0
    for m in range(NZ):
        acc += (A[7, m] - A[10, m] + A[8, m] + A[11, m]) * z[m]
    return acc


@jit_hot
def lti_fint(par, A, z0, z1, h, km, cs, quiet):
    """Time integral (N s) of the mesh force km * compression over an exact stretch z0 -> z1
    of h seconds (A: the stretch's z' = A z): the two-point Hermite rule with the force and
    its first two derivatives at both ends, h/2 (f0 + f1) + h^2/10 (f0' - f1') +
    h^3/120 (f0" + f1"), exact to degree 5 (error O(h^7): about 1e-8 of the force's swing at
    the sample spacing, 1/18 of the fastest mode's period). A quiet stretch (`lti_quiet`:
    the force stays within rtol of its static value, however long the stretch) takes the
    trapezoid, whose error is below that bound."""
    if cs == 1:
        return 0.0
    trap = 0.5 * h * km * (comp_of(par, z0, cs) + comp_of(par, z1, cs))
    if quiet:
        return trap
    d0 = z0[7] - z0[10] + z0[8] + z0[11]
    d1 = z1[7] - z1[10] + z1[8] + z1[11]
    dd = lti_dd(A, z0) + lti_dd(A, z1)
    return trap + km * h * h * ((d0 - d1) / 10.0 + h * dd / 120.0)


@jit
def lti_start(md, wk, pc, hs, km, tb):
    """Set up the exact steps of a piece from hs.y (z and its start copy in lti_vecs 0 and
    2): the propagator of the piece or of its sub-steps, and whether it is quiet."""
    y, Lv, Lm = hs.y, wk.lti_vecs, wk.lti_mats
    z, zs = Lv[0], Lv[2]
    htot = tb - pc.t0
    for m in range(12):
        z[m] = y[m]
    z[Z_A], z[Z_AD], z[Z_TQ], z[Z_ONE], z[Z_IU2] = y[Y_A], y[Y_AD], pc.torque, 1.0, 0.0
    for m in range(NZ):
        zs[m] = z[m]
    k = lti_slot(md, wk, pc, hs, km, htot)
    nsub = 1
    quiet = lti_quiet(md, Lm[k], z, pc.cs, Lm[L_SCRATCH + 8])
    if quiet:  # no event can fall: the start's force is all that is needed of it
        fm = km * comp_of(md.par, z, pc.cs)
    else:
        fm = events_at(md, wk, pc, hs, pc.t0, y, wk.gprev)
    record_force(wk.summary, fm)
    if not quiet:
        nsub = max(1, int(math.ceil(htot / md.par[P_SPACING] * (1.0 - 1e-12))))
        if nsub > 1:
            k = lti_slot(md, wk, pc, hs, km, htot / nsub)
    return LtiPiece(km, k, nsub, htot / nsub, quiet)


@jit
def lti_locate(md, wk, pc, hs, lp, t, tn):
    """Illinois on [t, tn] with the exact solution from z = lti_vecs[0]; the earliest
    falling function wins. Returns (its time from t, its index)."""
    Lm, Lv = wk.lti_mats, wk.lti_vecs
    z, zc, gc, E = Lv[0], Lv[3], Lv[4], Lm[L_SCRATCH + 9]
    h = tn - t
    best_tau = h
    best_e = np.int64(-1)
    tol = md.par[P_TTOL] + 8.0 * EPS * abs(t)
    for e in range(n_events(md, pc.nact, pc.cs)):
        if not (wk.gprev[e] > 0.0 and wk.g[e] <= 0.0):
            continue
        a, ga = 0.0, wk.gprev[e]
        b, gb = h, wk.g[e]
        side = np.int64(0)
        for _it in range(200):
            if b - a <= tol:
                break
            c = illinois_point(a, ga, b, gb)
            expm(Lm[lp.slot], c, E, Lm[L_SCRATCH:])
            matvec(E, z, zc)
            z_to_y(zc, wk.ytmp)
            events_at(md, wk, pc, hs, t + c, wk.ytmp, gc)
            a, ga, b, gb, side = illinois(a, ga, b, gb, c, gc[e], side)
        if best_e < 0 or b < best_tau:
            best_tau, best_e = b, e
    return best_tau, best_e


@jit
def lti_switch(md, wk, pc, hs, lp, t, tn, jumped):
    """A function fell in the sub-step [t, tn] (``jumped``: one that went to the end at
    once): locate it, finish the piece there and switch."""
    Lm, Lv = wk.lti_mats, wk.lti_vecs
    z, zn, zs = Lv[0], Lv[1], Lv[2]
    best_tau, best_e = lti_locate(md, wk, pc, hs, lp, t, tn)
    te = tn
    if best_tau < tn - t:
        te = t + best_tau
        expm(Lm[lp.slot], best_tau, Lm[L_SCRATCH + 9], Lm[L_SCRATCH:])
        matvec(Lm[L_SCRATCH + 9], z, zn)
    wk.summary[O_FINT] += lti_fint(md.par, Lm[lp.slot], z, zn, te - t, lp.km, pc.cs, jumped)
    lti_finish(md.par, hs.y, zs, zn, te - pc.t0, lp.km, pc.cs)
    end_piece(md, pc, hs, te)
    hs.mode[J_REL] = 0
    switch(md, wk, pc, hs, best_e, hs.clock[T_S])


@jit_hot
def lti_substep(md, wk, pc, hs, lp, ks, t, tb):
    """Sub-step ks (1-based) from t: zn = lti_vecs[1] <- its exact step (every 256 the
    rest in one when the transient has died out). Returns (ks, end of the sub-step,
    whether it went to the end at once)."""
    Lm, Lv = wk.lti_mats, wk.lti_vecs
    z, zn = Lv[0], Lv[1]
    jumped = False
    if ks % 256 == 0 and ks < lp.nsub and lti_quiet(md, Lm[lp.slot], z, pc.cs,
                                                    Lm[L_SCRATCH + 8]):
        kq = lti_slot(md, wk, pc, hs, lp.km, tb - t)
        matvec(Lm[L_NSLOT + kq], z, zn)
        ks = lp.nsub
        jumped = True
    else:
        matvec(Lm[L_NSLOT + lp.slot], z, zn)
    tn = tb if ks == lp.nsub else pc.t0 + ks * lp.hsub
    wk.summary[O_NSTEPS] += 1.0
    return ks, tn, jumped


@jit_hot
def lti_march(md, wk, pc, hs, lp, tb):
    """The sub-steps of a piece, each scanned for falls at its end; returns 1 after a
    switch, 0 on reaching tb, -2 when `flank_guard` stops it (a missed event it finds is
    located and switched instead, `events.mark_missed`, unless that cannot be done)."""
    z, zn = wk.lti_vecs[0], wk.lti_vecs[1]
    ng = n_events(md, pc.nact, pc.cs)
    t = pc.t0
    ks = 0
    ends = exact_terms(md, wk.lti_mats[lp.slot], z, lp.km, pc.cs)  # F, F', F'' (`extremes`)
    while ks < lp.nsub:
        ks, tn, jumped = lti_substep(md, wk, pc, hs, lp, ks + 1, t, tb)
        if lp.quiet:
            # one step: no event can fall, and the force at the end is the next piece's
            # start or the step's outputs, which the step's peak includes
            wk.summary[O_FINT] += lti_fint(md.par, wk.lti_mats[lp.slot], z, zn, tn - t, lp.km,
                                           pc.cs, lp.quiet)
        else:
            z_to_y(zn, wk.ytmp)
            fm = events_at(md, wk, pc, hs, tn, wk.ytmp, wk.g)
            hit = falls(wk, ng)
            if not hit and flank_guard(md, wk, pc, tn, wk.ytmp) != STATUS_OK:
                # a missed event: its start (gprev) marked, located as a fall
                if not mark_missed(md, wk, pc, wk.gprev, dte_noise(wk.ytmp, 0),
                                   dte_noise(z, 0)):
                    return -2
                hit = True
            if hit:
                lti_switch(md, wk, pc, hs, lp, t, tn, jumped)
                if not jumped:  # zn: the state at the switch
                    stretch_extremes(wk.summary, ends, exact_terms(
                        md, wk.lti_mats[lp.slot], zn, lp.km, pc.cs), hs.clock[T_T] - t)
                return 1
            record_force(wk.summary, fm)
            end_terms = evaluated_terms(wk, pc.cs)
            if not jumped:  # a jump is quiet: within rtol of the static force
                stretch_extremes(wk.summary, ends, end_terms, tn - t)
            ends = end_terms
            wk.summary[O_FINT] += lti_fint(md.par, wk.lti_mats[lp.slot], z, zn, tn - t, lp.km,
                                           pc.cs, jumped)
            for e in range(ng):
                wk.gprev[e] = wk.g[e]
        for m in range(NZ):
            z[m] = zn[m]
        t = tn
    lti_finish(md.par, hs.y, wk.lti_vecs[2], z, tb - pc.t0, lp.km, pc.cs)
    end_piece(md, pc, hs, tb)
    return 0


@jit_hot
def piece_lti(md, wk, pc, hs, tb):
    """`piece` for constant coefficients: exact steps z <- expm(A h) z. A quiet piece
    (`lti_quiet`) is one step; otherwise steps of at most the sample spacing are scanned for
    falls through zero, refined by Illinois on the exact solution."""
    mp = md.par
    km = 0.0
    for i in range(pc.nact):
        xi = pair_xi(mp, pc.s0, wk.active[i])
        km += pair_k(md, xi, xi, pc.nact)
    htot = tb - pc.t0
    if not (htot > 16.0 * EPS * max(abs(pc.t0), 1e-300)):
        end_piece(md, pc, hs, tb)
        return 0
    lp = lti_start(md, wk, pc, hs, km, tb)
    if not lp.quiet:  # (a quiet piece holds its contact: `lti_quiet`)
        e = start_flanks(md, pc, wk.gprev, hs.y)
        if e >= 0:  # a flank in tension, or overlapping flanks apart: that switch is due now
            switch(md, wk, pc, hs, e, pc.s0)
            return 1
    return lti_march(md, wk, pc, hs, lp, tb)
