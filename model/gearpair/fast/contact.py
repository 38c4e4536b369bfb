"""Contact-state evaluation and the right-hand side (compiled): `equations.evaluate` for one
contact state, its event functions (`switching.event_values`) and the energy quadratures.

Every function reads the model from a `ModelData` record ``md`` and writes its results into
the `Work` record ``wk`` (per-pair rows ``wk.pair``, scalars ``wk.scal``); a `Piece` ``pc``
holds the inputs, the pair set and the contact code.
"""

from __future__ import annotations

import math

import numpy as np

from ..jitcache import jit, jit_hot
from . import detmath as dm  # exp, tanh: the same bits on every CPU, not the C library's
from .layout import (
    FR_NOMINAL,
    FR_REG,
    FR_STICK,
    I_BACK,
    I_FRIC,
    I_KIND,
    I_NP,
    I_NTAB,
    I_SEP,
    I_SLIDE,
    I_TIE,
    I_TORS,
    I_VARY,
    KIND_CONSTANT,
    KIND_CUBIC,
    P_BACK,
    P_C,
    P_CM,
    P_DX,
    P_INVDX,
    P_IPER,
    P_IRB1,
    P_IRB2,
    P_KB,
    P_KMEAN,
    P_L,
    P_MINV,
    P_MU,
    P_MUS,
    P_PB,
    P_PER,
    P_RATIO,
    P_RB1,
    P_RB2,
    P_S1A,
    P_S1S2,
    P_VEPS,
    P_VS,
    S_COMP,
    S_DDELTA,
    S_DELTA,
    S_F,
    S_KM,
    S_QDD,
    S_THETA,
    W_DK,
    W_F,
    W_K,
    W_LAMEX,
    W_N,
    W_NOM,
    W_S1M,
    W_S2M,
    W_STK,
    W_V,
    W_XI,
    Y_A,
    Y_AD,
)


@jit_hot
def back_compression(par, delta):
    """Compression (m) of the back flanks at DTE ``delta``: delta + b (b = `Effects.backlash`;
    negative while they are pressed together)."""
    return delta + par[P_BACK]


@jit_hot
def dte_of(y):
    """The dynamic transmission error (m) of the state (or propagator state) ``y``: the mesh
    deflection delta = y1 - y2 + u1 + u2 along the line of action, Eq. (3)."""
    return y[1] - y[4] + y[2] + y[5]


@jit_hot
def flank_compression(par, delta, cs):
    """Mesh compression (m) of contact code ``cs`` at DTE ``delta``: delta on the drive
    flanks, `back_compression` on the back flanks (cs 2); the mesh force is km times it
    (apart, cs 1, the callers use none)."""
    return back_compression(par, delta) if cs == 2 else delta


@jit_hot
def sgn(x, fallback):
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return fallback


@jit_hot
def wrap(x, per):
    """x mod per in [0, per) (numpy's mod for a positive divisor)."""
    r = x - per * math.floor(x * (1.0 / per))
    if r >= per:
        r -= per
    if r < 0.0:
        r = 0.0
    return r


@jit_hot
def pair_xi(par, s, j):
    """Position from A of tracked pair j held in contact at mesh travel s (Model.contact)."""
    per, L = par[P_PER], par[P_L]
    x = s + j * par[P_PB]
    xi = x - per * math.floor(x * par[P_IPER])
    if xi >= per:
        xi -= per
    if xi < 0.0:
        xi = 0.0
    if xi > 0.5 * (L + per):
        xi -= per
    return min(max(xi, 0.0), L)


@jit_hot
def table_index(md, x):
    """Interval of the (uniform) stiffness table holding position x, clipped to the table."""
    i = int(math.floor(x * md.par[P_INVDX]))
    return min(max(i, 0), md.flag[I_NTAB] - 2)


@jit_hot
def pair_k(md, xi, xi_idx, nact):
    """Stiffness of a pair at xi, on the table interval that holds xi_idx (the same one
    over a step, so that a step ending on a knot uses the interval it integrated over)."""
    if md.flag[I_KIND] == KIND_CONSTANT:
        return md.par[P_KMEAN] / max(nact, 1)
    tk = md.k_coef
    i = table_index(md, xi_idx)
    d = xi - md.xi_knots[i]
    if md.flag[I_KIND] == KIND_CUBIC:
        c = 4 * i
        return ((tk[c + 3] * d + tk[c + 2]) * d + tk[c + 1]) * d + tk[c]
    return tk[i] + d * md.k_slope[i]


@jit_hot
def pair_k_and_slope(md, xi, xi_idx, nact):
    """`pair_k` and its slope d k/d xi (N/m per m), from one table look-up."""
    if md.flag[I_KIND] == KIND_CONSTANT:
        return md.par[P_KMEAN] / max(nact, 1), 0.0
    tk = md.k_coef
    i = table_index(md, xi_idx)
    d = xi - md.xi_knots[i]
    if md.flag[I_KIND] == KIND_CUBIC:
        c = 4 * i
        return (((tk[c + 3] * d + tk[c + 2]) * d + tk[c + 1]) * d + tk[c],
                (3.0 * tk[c + 3] * d + 2.0 * tk[c + 2]) * d + tk[c + 1])
    return tk[i] + d * md.k_slope[i], md.k_slope[i]


@jit
def active_at(md, s, act):
    """Tracked pairs on the path of contact at s (0 <= xi < L); returns their number."""
    n = 0
    for j in range(md.flag[I_NP]):
        xi = wrap(s + j * md.par[P_PB], md.par[P_PER])
        if 0.0 <= xi < md.par[P_L]:
            act[n] = j
            n += 1
    return n


@jit
def solve_small(Sm, n, nrhs):
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


@jit_hot
def mesh_forces(md, wk, pc, s, s_idx, y):
    """Pair geometry and stiffness, the DTE and the support, mesh and input forces of one
    contact state into ``wk`` (Eqs. (1)-(8)); no friction yet."""
    mp, pw, sc = md.par, wk.pair, wk.scal
    km = 0.0
    for i in range(pc.nact):
        xi = pair_xi(mp, s, wk.active[i])
        pw[W_XI, i] = xi
        s1m = mp[P_S1A] + xi
        pw[W_S1M, i] = s1m
        pw[W_S2M, i] = mp[P_S1S2] - s1m
        k, dk = pair_k_and_slope(md, xi, xi + (s_idx - s), pc.nact)
        pw[W_DK, i] = dk
        pw[W_K, i] = k
        km += k
    delta = dte_of(y)
    ddelta = y[7] - y[10] + y[8] + y[11]
    cs = pc.cs
    theta = 0.0 if cs == 1 else 1.0
    comp = 0.0 if cs == 1 else flank_compression(mp, delta, cs)
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
    sc[S_F + 2] += pc.torque * mp[P_IRB1]
    sc[S_F + 5] += mp[P_KB + 5] * y[Y_A] + mp[P_C + 5] * y[Y_AD]  # load-shaft end


@jit_hot
def sliding_mu(par, v):
    """Coefficient of sliding friction at sliding velocity v (`equations.sliding_coefficient`):
    mu, or with a Stribeck velocity v_s, mu + (mu_static - mu) exp(-(v / v_s)^2)."""
    if par[P_VS] == 0.0:
        return par[P_MU]
    r = v / par[P_VS]
    return par[P_MU] + (par[P_MUS] - par[P_MU]) * dm.exp(-(r * r))


@jit_hot
def friction_forces(md, wk, pc, s, s_idx, y, dirs, stuck):
    """Normal forces, sliding velocities (Eqs. (12)-(13)) and the friction of the slipping
    pairs by the friction law; returns the number of stuck pairs (their friction is
    `static_friction`'s)."""
    mp, pw, sc = md.par, wk.pair, wk.scal
    irb1, irb2, speed, mu = mp[P_IRB1], mp[P_IRB2], pc.speed, mp[P_MU]  # kinetic mu
    fric = md.flag[I_FRIC]
    full = md.flag[I_SLIDE] == 1
    delta = sc[S_DELTA]
    ns = np.int64(0)  # typed, not a literal: no second compile of its callees
    for i in range(pc.nact):
        j = wk.active[i]
        s1m, s2m = pw[W_S1M, i], pw[W_S2M, i]
        normal = pw[W_K, i] * delta if pc.cs == 0 else 0.0  # friction on the drive flanks
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
            f = mu * abs(normal) * sgn(nom - speed * (1.0 + mp[P_RATIO]) * (s_idx - s), 0.0)
        elif fric == FR_REG:
            f = sliding_mu(mp, v) * abs(normal) * dm.tanh(v / mp[P_VEPS])
        elif fric == FR_STICK:
            if stuck[j] != 0:
                pw[W_STK, i] = 1.0
                ns += 1
            else:
                f = sliding_mu(mp, v) * abs(normal) * dirs[j]
        pw[W_F, i] = f
        if f != 0.0:
            sc[S_F + 0] -= f
            sc[S_F + 2] += f * s1m * irb1
            sc[S_F + 3] += f
            sc[S_F + 5] += f * s2m * irb2
    return ns


@jit_hot
def pin_supports(sc):
    """Torsional model: no forces on x1, y1, x2, y2 (rigid supports), which stay at 0."""
    sc[S_F + 0] = 0.0
    sc[S_F + 1] = 0.0
    sc[S_F + 3] = 0.0
    sc[S_F + 4] = 0.0


@jit_hot
def static_friction_system(md, wk, pc, y, ns):
    """Rows a_a, columns w_b of the stuck pairs' system (equations.static_friction) into
    ``wk.solve``; rhs -(c + a M^-1 F) for the chosen tie (column ns) and the exact tie
    (column ns + 1)."""
    mp, pw, sc, Sm = md.par, wk.pair, wk.scal, wk.solve
    rb1, rb2, speed = mp[P_RB1], mp[P_RB2], pc.speed
    full = md.flag[I_SLIDE] == 1
    rate = -(1.0 + mp[P_RATIO]) * rb1 * speed * speed
    turn = 0.0
    if full:
        turn = -(speed * y[8] - rb1 * speed / rb2 * y[11])
    tr = 0.0 if md.flag[I_TORS] != 0 else 1.0
    ra = 0
    for ia in range(pc.nact):
        if pw[W_STK, ia] == 0.0:
            continue
        wa2, wa5 = pw[W_S1M, ia] / rb1, pw[W_S2M, ia] / rb2
        rb = 0
        for ib in range(pc.nact):
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
        c_tie = turn + (rate if md.flag[I_TIE] == 0 else 0.0)
        Sm[ra, ns] = -(c_tie + aF)
        Sm[ra, ns + 1] = -(turn + rate + aF)
        ra += 1


@jit_hot
def static_friction(md, wk, pc, y, ns):
    """Static friction of the ``ns`` stuck pairs: solve their system and apply it."""
    mp, pw, sc, Sm = md.par, wk.pair, wk.scal, wk.solve
    rb1, rb2 = mp[P_RB1], mp[P_RB2]
    static_friction_system(md, wk, pc, y, ns)
    solve_small(Sm, ns, Sm.shape[1] - Sm.shape[0])  # 2 right-hand sides
    ra = 0
    for i in range(pc.nact):
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
    if md.flag[I_TORS] != 0:
        pin_supports(sc)


@jit_hot
def evaluate(md, wk, pc, s, s_idx, y, dirs, stuck):
    """`equations.evaluate` for one contact state at mesh travel s, into ``wk``.

    ``y`` holds q (0..5) and q' (6..11); ``dirs``/``stuck`` are over the tracked pairs;
    ``s_idx`` is the mesh travel that picks the stiffness-table interval (see `pair_k`).
    """
    mesh_forces(md, wk, pc, s, s_idx, y)
    ns = friction_forces(md, wk, pc, s, s_idx, y, dirs, stuck)
    if md.flag[I_TORS] != 0:
        pin_supports(wk.scal)
    if ns > 0:
        static_friction(md, wk, pc, y, ns)
    sc = wk.scal
    for m in range(6):
        sc[S_QDD + m] = md.par[P_MINV + m] * sc[S_F + m]


@jit_hot
def n_sep_events(md, cs):
    """Number of flank events: 1 (leave/regain contact), 2 apart with a back flank."""
    if md.flag[I_SEP] == 0:
        return 0
    return 2 if (cs == 1 and md.flag[I_BACK] != 0) else 1


@jit_hot
def n_events(md, nact, cs):
    n = n_sep_events(md, cs)
    if md.flag[I_FRIC] == FR_STICK and cs == 0:
        n += nact
    return n


@jit_hot
def sep_event_values(md, cs, d, g):
    """Separation events of contact code ``cs`` at DTE ``d`` into g; returns their count."""
    if md.flag[I_SEP] == 0:
        return 0
    if cs == 0:
        g[0] = d
    elif cs == 2:
        g[0] = -back_compression(md.par, d)
    else:
        g[0] = -d
        if md.flag[I_BACK] != 0:
            g[1] = back_compression(md.par, d)
    return n_sep_events(md, cs)


@jit_hot
def event_values(md, wk, pc, dirs, g):
    """`switching.event_values` of the evaluated state in ``wk``: positive while it holds."""
    pw = wk.pair
    n = sep_event_values(md, pc.cs, wk.scal[S_DELTA], g)
    if md.flag[I_FRIC] == FR_STICK and pc.cs == 0:
        for i in range(pc.nact):
            if pw[W_STK, i] != 0.0:
                lam = abs(pw[W_F, i])
                if md.flag[I_TIE] == 1:
                    lam = min(lam, abs(pw[W_LAMEX, i]))
                g[n] = md.par[P_MUS] * abs(pw[W_N, i]) - lam  # Eq. (14), static mu
            else:
                g[n] = dirs[wk.active[i]] * pw[W_V, i]
            n += 1
    return n


@jit
def param_rate(md, wk, pc, s_idx, y):
    """Parametric power 0.5 (d km/dt) compression^2 on the table intervals at s_idx (W)."""
    mp = md.par
    if md.flag[I_VARY] == 0 or pc.cs == 1:
        return 0.0
    dkm = 0.0
    for i in range(pc.nact):
        dkm += md.k_slope[table_index(md, pair_xi(mp, s_idx, wk.active[i]))]
    comp = flank_compression(mp, dte_of(y), pc.cs)
    return 0.5 * dkm * mp[P_RB1] * pc.speed * comp * comp


@jit_hot
def rhs(md, wk, pc, hs, t, s_idx, y, dy):
    """Right-hand side of one contact state with the four energy quadratures."""
    mp, pw, sc = md.par, wk.pair, wk.scal
    rb1 = mp[P_RB1]
    s = pc.s0 + rb1 * pc.speed * (t - pc.t0)
    evaluate(md, wk, pc, s, s_idx, y, hs.dirs, hs.stuck)
    for m in range(6):
        dy[m] = y[6 + m]
        dy[6 + m] = sc[S_QDD + m]
    theta = sc[S_THETA]
    ad = y[Y_AD]
    dy[12] = pc.torque * mp[P_IRB1] * y[8] - (mp[P_KB + 5] * (y[5] - y[Y_A])
                                              + mp[P_C + 5] * (y[11] - ad)) * ad
    d = 0.0
    for m in range(5):
        d += mp[P_C + m] * y[6 + m] * y[6 + m]
    d += mp[P_C + 5] * (y[11] - ad) * (y[11] - ad)
    dy[13] = d + theta * mp[P_CM] * sc[S_DDELTA] * sc[S_DDELTA]
    dy[Y_A] = ad
    dy[Y_AD] = 0.0
    pf = 0.0
    for i in range(pc.nact):
        f = pw[W_F, i]
        if f != 0.0:
            wq = (-y[6] + pw[W_S1M, i] * mp[P_IRB1] * y[8] + y[9]
                  + pw[W_S2M, i] * mp[P_IRB2] * y[11])
            pf += f * wq
    dy[14] = pf
    if md.flag[I_VARY] != 0:
        dkm = 0.0
        for i in range(pc.nact):
            dkm += pw[W_DK, i]
        dy[15] = 0.5 * dkm * rb1 * pc.speed * sc[S_COMP] * sc[S_COMP]
    else:
        dy[15] = 0.0


@jit
def next_knot_dt(md, s, speed, act, nact):
    """Time until an active pair reaches the next knot of the stiffness table (inf if none).

    A table law (linear) has a kink at every knot, a spline a jump in its third derivative;
    a Runge-Kutta step across one loses its order, so steps end on knots (the step sequence
    continues: the state is C^1 there).
    """
    mp = md.par
    if md.flag[I_VARY] == 0 or md.flag[I_NTAB] <= 2 or speed == 0.0:
        return np.inf
    dx, L = mp[P_DX], mp[P_L]
    v1 = mp[P_RB1] * speed
    guard = 1e-9 * dx
    best = np.inf
    for i in range(nact):
        xi = pair_xi(mp, s, act[i])
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


@jit_hot
def pair_v(md, s, y, speed, j):
    """Sliding velocity of tracked pair j (the arithmetic of `friction_forces`, to the bit)."""
    mp = md.par
    xi = pair_xi(mp, s, j)
    s1m = mp[P_S1A] + xi
    s2m = mp[P_S1S2] - s1m
    nom = speed * (mp[P_RATIO] * s2m - s1m)
    if md.flag[I_SLIDE] == 1:
        return nom - (-y[6] + s1m * mp[P_IRB1] * y[8] + y[9] + s2m * mp[P_IRB2] * y[11])
    return nom + y[6] - y[9]
