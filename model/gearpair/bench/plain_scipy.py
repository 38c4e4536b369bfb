"""The gear pair as a scipy user would write it: what `gearpair bench` compares the fast core with.

The same model as the package (Xun, Dai, Wang 2023: 6 DOF, Eqs. (1)-(25); potential-energy
or rectangular mesh stiffness, tooth separation, Coulomb friction in the nominal direction or
stick-slip by Eq. (14)), written the plain way: a right-hand side per contact state (slip,
stick, separated), `scipy.integrate.solve_ivp` with terminal events for the switches, and a
restart after each event with the new state. It takes from `gearpair` only data: the Table 1
parameters, the derived geometry and the per-pair stiffness law (so that both sides
integrate the same equations); nothing of the package's engines or switching code.

It is written as a careful scipy user writes it (issue 37; docs/bench.md, "The plain-scipy
anchor"): the right-hand side and the event functions work on Python floats, because numpy's
per-call overhead on 12-element arrays costs more than the arithmetic; the stiffness spline's
coefficients are plain lists read once; the event functions compute only the quantity they
watch; a restart builds two small closures and nothing else. It stays plain: `solve_ivp`,
numpy and scipy, no compiled code.

What a user knows and uses: the instants where a tooth pair enters or leaves the path of
contact (and, for nominal friction, passes the pitch point) follow from the constant speed,
so `solve_ivp` runs between them; the unknown switches (teeth separate or touch again, a
sliding velocity reverses, static friction exceeds ``mu`` times the normal force) are events
that `solve_ivp` locates on its dense output. Like every such code it compares event signs
at step ends only, so a switch that begins and ends inside one step would be lost; the bench
prints its error against the fast engine's tight reference, which shows whether it was.

It ships in the package (an installed ``gearpair bench`` has its rows) but stays apart from
the engines: it imports the package's data modules only, and the fast engine only to compare
(`compare_with_fast`; tests/test_plain_scipy.py checks both). Run it to compare it with the
fast engine at the bench's operating point::

    python -m gearpair.bench.plain_scipy [--t-end 0.02] [--rtol 1e-9] [--method DOP853]
        [--stiffness rectangular] [--friction stick_slip] [--torque 3900] [--rpm 100]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

FRICTION = ("off", "nominal", "stick_slip")
STIFFNESS = ("potential_energy", "rectangular")
G = np.array([0.0, 1.0, 1.0, 0.0, -1.0, 1.0])  # delta = y1 - y2 + u1 + u2, Eq. (3)
MAX_EVENTS_AT_ONE_INSTANT = 50
# A sliding velocity counts as reversed once it is this far (m/s) past zero. A pair released
# from stick starts sliding at v = 0 exactly with d v/dt = 0 (the release is where static
# friction reaches mu |N|): without the margin, rounding (1e-16 m/s) can make its event fall
# at once, and the release repeat at one instant. 1e-12 m/s delays a true reversal by about
# 1e-14 s (d v/dt is tens of m/s^2 there).
V_REVERSED = 1e-12


@dataclass(frozen=True)
class Data:
    """Table 1 gear pair reduced to numbers (SI): masses, supports, geometry, stiffness.

    The per-pair stiffness is a piecewise cubic in the position ``xi`` along the path of
    contact on uniform knots: the potential-energy law's spline, or for the rectangular law
    one interval with the constant per-pair stiffness.
    """

    minv: np.ndarray   # diagonal of M^-1, Eq. (5) (1/kg)
    c: np.ndarray      # support damping diagonal (N.s/m)
    kb: np.ndarray     # support stiffness diagonal (N/m)
    rb1: float
    rb2: float
    ratio: float       # z1 / z2
    cm: float          # mesh damping (N.s/m)
    mu: float
    pb: float          # base pitch (m)
    length: float      # path of contact AE (m)
    s1a: float         # S1A (m)
    s1s2: float        # S1S2 (m)
    xi_pitch: float    # pitch point from A (m)
    n_pairs: int
    knots: np.ndarray  # stiffness knots (m) and coefficients per interval (N/m, N/m^2, ...)
    coef: np.ndarray
    stiffness: str = "potential_energy"

    @classmethod
    def table1(cls, stiffness: str = "potential_energy") -> Data:
        """Table 1 with the stiffness law ``stiffness`` (one of `STIFFNESS`)."""
        from gearpair.effects import StiffnessSpec
        from gearpair.geometry import Geometry
        from gearpair.params import GearParams
        from gearpair.stiffness import MeshStiffness

        if stiffness not in STIFFNESS:
            raise ValueError(f"stiffness = {stiffness!r}; choose one of {', '.join(STIFFNESS)}")
        p = GearParams()
        g = Geometry.from_params(p)
        k = MeshStiffness.build(p, g, StiffnessSpec(stiffness))
        if stiffness == "rectangular":  # the same k0 on all of [0, L]: one constant piece
            knots, coef = k.xi, np.array([[k.k[0], 0.0, 0.0, 0.0]])
        else:
            knots, coef = k.xi, k.cubic
        return cls(
            minv=1.0 / np.array([p.m1, p.m1, p.mu1, p.m2, p.m2, p.mu2]),
            c=np.array([p.cb1, p.cb1, p.cr1, p.cb2, p.cb2, p.cr2]),
            kb=np.array([p.kb1, p.kb1, p.kr1, p.kb2, p.kb2, p.kr2]),
            rb1=p.rb1, rb2=p.rb2, ratio=p.ratio, cm=p.cm, mu=p.mu, pb=g.base_pitch,
            length=g.path_length, s1a=g.s1a, s1s2=g.s1s2, xi_pitch=g.xi_pitch,
            n_pairs=g.n_pairs, knots=knots, coef=coef, stiffness=stiffness)


class PlainGearPair:
    """The model integrated by `solve_ivp`, one contact state at a time.

    Parameters
    ----------
    friction : {"off", "nominal", "stick_slip"}
        ``nominal``: Coulomb friction in the direction of the nominal sliding velocity;
        ``stick_slip``: sign law with stick by Eq. (14).
    rtol : float
        Relative tolerance; atol is rtol times 1e-5 m for positions, 1e-3 m/s for rates.
    method : str
        Any `solve_ivp` method.
    torque : float
        Driving torque (N.m).
    rpm : float
        Speed of gear 1 (r/min).
    data : Data, optional
        The gear pair; default `Data.table1` with ``stiffness``.
    stiffness : {"potential_energy", "rectangular"}
        Per-pair mesh stiffness law (used when ``data`` is not given).

    Notes
    -----
    The state is ``y = (q, q')`` with ``q = (x1, y1, u1, x2, y2, u2)`` in m. In contact the
    forces are Eqs. (4)-(11): supports, the mesh spring-damper along ``G`` and per pair the
    friction ``mu k_j |delta| d_j`` along ``w_j``, affine in the pair's position ``xi_j``.
    """

    def __init__(self, friction: str = "stick_slip", rtol: float = 1e-9,
                 method: str = "DOP853", torque: float = 3900.0, rpm: float = 100.0,
                 data: Data | None = None, stiffness: str = "potential_energy") -> None:
        if friction not in FRICTION:
            raise ValueError(f"friction = {friction!r}; choose one of {', '.join(FRICTION)}")
        self.d = d = data or Data.table1(stiffness)
        self.friction, self.rtol, self.method = friction, rtol, method
        self.atol = rtol * np.r_[np.full(6, 1e-5), np.full(6, 1e-3)]
        self.torque, self.speed = torque, rpm * math.pi / 30.0
        self.vs = d.rb1 * self.speed  # contact points move along the LOA (m/s)
        self.n_events = 0
        self.load = np.array([0.0, 0.0, torque / d.rb1, 0.0, 0.0, 0.0])  # Eq. (10) (N)
        # The right-hand side reads these as Python floats: indexing a numpy array yields
        # numpy scalars, whose arithmetic costs several times that of floats
        self.minv, self.c, self.kb = d.minv.tolist(), d.c.tolist(), d.kb.tolist()
        self.h, self.last = float(d.knots[1] - d.knots[0]), len(d.knots) - 2
        self.knot_list = d.knots.tolist()
        self.c0, self.c1, self.c2, self.c3 = (d.coef[:, j].tolist() for j in range(4))
        # w_j (Eq. (9)) is affine in xi_j with non-zero entries on x1, u1, x2, u2 only:
        # w_j = (-1, 0, s1a/rb1 + xi_j/rb1, 1, 0, (s1s2 - s1a)/rb2 - xi_j/rb2)
        self.w_u1, self.w_u2 = d.s1a / d.rb1, (d.s1s2 - d.s1a) / d.rb2
        self.dw_u1, self.dw_u2 = 1.0 / d.rb1, -1.0 / d.rb2
        # the nominal sliding velocity (Eq. (12)) is affine in xi too
        self.nominal_at_a = self.speed * (d.ratio * (d.s1s2 - d.s1a) - d.s1a)
        self.dnominal_dxi = -self.speed * (1.0 + d.ratio)
        # d v_j / dt of a stuck pair = x1'' - x2'' + this rate of the nominal part (m/s^2)
        self.nominal_rate = self.dnominal_dxi * self.vs

    # -- the model at one instant ------------------------------------------------------------
    def stiffness(self, xi: np.ndarray) -> np.ndarray:
        """Per-pair mesh stiffness (N/m) at positions ``xi`` (m) from A, vectorized."""
        # positions stay in [0, L] within a segment; L itself falls on the last interval
        i = np.minimum((np.asarray(xi) * (1.0 / self.h)).astype(np.intp), self.last)
        x = xi - self.d.knots[i]
        coef = self.d.coef
        return ((coef[i, 3] * x + coef[i, 2]) * x + coef[i, 1]) * x + coef[i, 0]

    def k_at(self, xi: float) -> float:
        """Per-pair mesh stiffness (N/m) at one position ``xi`` (m), in floats."""
        i = int(xi * (1.0 / self.h))  # the interval as `stiffness` and the rhs find it
        if i > self.last:
            i = self.last
        x = xi - self.knot_list[i]
        return ((self.c3[i] * x + self.c2[i]) * x + self.c1[i]) * x + self.c0[i]

    def holding_force(self, fx1: float, fx2: float) -> float:
        """Static friction (N) that holds a stuck pair: d v_j/dt = 0 (Eqs. (15), (18), exact
        tie), from the forces along x on both gears (N) without it.

        v_j = nominal_j + x1' - x2' and w_j has -1 on x1, +1 on x2 for every pair, so the
        constraint is one scalar equation: ix1 (fx1 - lam) - ix2 (fx2 + lam) + rate = 0.
        """
        ix1, ix2 = self.minv[0], self.minv[3]
        return (self.nominal_rate + ix1 * fx1 - ix2 * fx2) / (ix1 + ix2)

    def contact_rhs(self, seg: Segment, dirs: list[float], stuck: int):
        """Right-hand side ``f(t, y)`` with the teeth in contact: the pairs of ``seg`` slide
        in directions ``dirs`` (+1, -1), except pair ``stuck`` (index in ``seg``, -1: none)
        held by static friction (a Lagrange multiplier, `holding_force`).

        Written out in floats, row by row, with everything the state does not change bound
        to locals of the closure.
        """
        ix1, iy1, iu1, ix2, iy2, iu2 = self.minv
        cx1, cy1, cu1, cx2, cy2, cu2 = self.c
        kx1, ky1, ku1, kx2, ky2, ku2 = self.kb
        load, cm, vs, t0 = float(self.load[2]), self.d.cm, self.vs, seg.t0
        w1, w2, dw1, dw2 = self.w_u1, self.w_u2, self.dw_u1, self.dw_u2
        mu = 0.0 if self.friction == "off" else self.d.mu
        # (position at t0, kinetic friction direction: 0 for the stuck pair)
        pairs = [(x0, 0.0 if i == stuck else di)
                 for i, (x0, di) in enumerate(zip(seg.xi0.tolist(), dirs, strict=True))]
        xs0 = seg.xi0[stuck].item() if stuck >= 0 else 0.0
        hold = self.holding_force
        # `k_at` inlined: a method call per pair costs as much as the spline's arithmetic
        knots, c0, c1, c2, c3 = self.knot_list, self.c0, self.c1, self.c2, self.c3
        inv_h, last = 1.0 / self.h, self.last

        def rhs(t, y):
            x1, y1, u1, x2, y2, u2, vx1, vy1, vu1, vx2, vy2, vu2 = y.tolist()
            travel = vs * (t - t0)
            delta = y1 + u1 - y2 + u2
            mud = mu * abs(delta)
            ktot = s = p = 0.0  # total stiffness; sum f_j and sum f_j xi_j of the friction
            for x0, di in pairs:
                xi = x0 + travel
                i = int(xi * inv_h)
                if i > last:
                    i = last
                x = xi - knots[i]
                k = ((c3[i] * x + c2[i]) * x + c1[i]) * x + c0[i]
                ktot += k
                f = k * mud * di
                s += f
                p += f * xi
            fmesh = ktot * delta + cm * (vy1 + vu1 - vy2 + vu2)
            fx1 = -cx1 * vx1 - kx1 * x1 - s
            fx2 = -cx2 * vx2 - kx2 * x2 + s
            if stuck >= 0:
                lam = hold(fx1, fx2)
                fx1 -= lam
                fx2 += lam
                s += lam
                p += lam * (xs0 + travel)
            return [vx1, vy1, vu1, vx2, vy2, vu2,
                    ix1 * fx1,
                    iy1 * (-cy1 * vy1 - ky1 * y1 - fmesh),
                    iu1 * (load - cu1 * vu1 - ku1 * u1 - fmesh + w1 * s + dw1 * p),
                    ix2 * fx2,
                    iy2 * (-cy2 * vy2 - ky2 * y2 + fmesh),
                    iu2 * (-cu2 * vu2 - ku2 * u2 - fmesh + w2 * s + dw2 * p)]

        return rhs

    def separated_rhs(self):
        """Right-hand side ``f(t, y)`` with the teeth apart: no mesh force, no mesh damping,
        no friction (Eq. (8)); supports and load only."""
        ix1, iy1, iu1, ix2, iy2, iu2 = self.minv
        cx1, cy1, cu1, cx2, cy2, cu2 = self.c
        kx1, ky1, ku1, kx2, ky2, ku2 = self.kb
        load = float(self.load[2])

        def rhs(t, y):
            x1, y1, u1, x2, y2, u2, vx1, vy1, vu1, vx2, vy2, vu2 = y.tolist()
            return [vx1, vy1, vu1, vx2, vy2, vu2,
                    ix1 * (-cx1 * vx1 - kx1 * x1), iy1 * (-cy1 * vy1 - ky1 * y1),
                    iu1 * (load - cu1 * vu1 - ku1 * u1),
                    ix2 * (-cx2 * vx2 - kx2 * x2), iy2 * (-cy2 * vy2 - ky2 * y2),
                    iu2 * (-cu2 * vu2 - ku2 * u2)]

        return rhs

    def static_friction(self, seg: Segment, dirs: list[float], j: int, t: float,
                        y: np.ndarray) -> tuple[float, float]:
        """Static friction (N) holding pair ``j`` of ``seg`` stuck while the others slide in
        ``dirs``, and its normal force (N): only the x rows of the forces are needed."""
        travel = self.vs * (t - seg.t0)
        delta = float(y[1] + y[2] - y[4] + y[5])
        mud = (0.0 if self.friction == "off" else self.d.mu) * abs(delta)
        s, normal = 0.0, 0.0
        for i, x0 in enumerate(seg.xi0.tolist()):
            k = self.k_at(x0 + travel)
            if i == j:
                normal = k * delta
            else:
                s += k * mud * dirs[i]
        fx1 = -self.c[0] * float(y[6]) - self.kb[0] * float(y[0]) - s
        fx2 = -self.c[3] * float(y[9]) - self.kb[3] * float(y[3]) + s
        return self.holding_force(fx1, fx2), normal

    def sliding(self, t: float, y: np.ndarray, seg: Segment, i: int) -> float:
        """Sliding velocity of pair i in contact (m/s), Eq. (12)."""
        xi = seg.xi0[i].item() + self.vs * (t - seg.t0)
        return self.nominal_at_a + self.dnominal_dxi * xi + float(y[6] - y[9])

    # -- events: positive while the state holds, falling through zero when it ends ----------
    def events(self, seg: Segment, state: str, dirs: list[float], stuck: int) -> list:
        """Terminal event functions of a state: contact (delta) or separation (-delta), then
        per pair in contact its stick margin (stuck) or d v (slipping in direction d). Each
        computes the one quantity it watches, in floats."""
        if state == "separated":
            evs = [lambda t, y: -float(y[1] + y[2] - y[4] + y[5])]
        else:
            evs = [lambda t, y: float(y[1] + y[2] - y[4] + y[5])]
        if state != "separated" and self.friction == "stick_slip":
            mu = self.d.mu
            for i in range(len(seg.pairs)):
                if i == stuck:
                    def margin(t, y, i=i):  # Eq. (14): mu |N_i| - |lambda_i|
                        lam, normal = self.static_friction(seg, dirs, i, t, y)
                        return mu * abs(normal) - abs(lam)
                    evs.append(margin)
                else:
                    evs.append(lambda t, y, i=i:
                               dirs[i] * self.sliding(t, y, seg, i) + V_REVERSED)
        for e in evs:
            e.terminal, e.direction = True, -1
        return evs

    # -- the run -----------------------------------------------------------------------------
    def boundaries(self, t_end: float) -> np.ndarray:
        """Instants (s) in (0, t_end) where a pair enters or leaves contact (or, for nominal
        friction, passes the pitch point): mesh travel k pb + offset."""
        d = self.d
        offsets = [0.0, math.fmod(d.length, d.pb)]
        if self.friction == "nominal":
            offsets.append(math.fmod(d.xi_pitch, d.pb))
        s_end = self.vs * t_end
        out = [(k * d.pb + o) / self.vs for o in offsets
               for k in range(math.ceil(s_end / d.pb) + 1) if 0.0 < k * d.pb + o < s_end]
        return np.unique(out)

    def segment(self, ta: float, tb: float) -> Segment:
        """Pairs in contact between two boundaries (s), and their positions (m) at ``ta``."""
        d = self.d
        s_mid = self.vs * 0.5 * (ta + tb)
        xi_mid = np.mod(s_mid + np.arange(d.n_pairs) * d.pb, d.n_pairs * d.pb)
        pairs = np.flatnonzero(xi_mid < d.length)
        return Segment(ta, pairs, xi_mid[pairs] - self.vs * (0.5 * (tb - ta)))

    def simulate(self, t_end: float, dt: float = 1e-4) -> dict:
        """Run from the static equilibrium at t = 0 to ``t_end`` (s) and record every ``dt``
        (s): time (s), DTE (m), mesh force (N)."""
        n = self.d.n_pairs
        grid = np.arange(int(round(t_end / dt)) + 1) * dt
        self.rec = {"dte": np.full(len(grid), np.nan), "mesh_force": np.full(len(grid), np.nan)}
        self.grid = grid
        seg = self.segment(0.0, min(t_end, 1e-9))
        k0 = self.stiffness(seg.xi0).sum()
        y = np.zeros(12)
        y[:6] = np.linalg.solve(np.diag(self.d.kb) + k0 * np.outer(G, G), self.load)
        self.dirs, self.stuck = np.ones(n), np.zeros(n, dtype=bool)
        self.state = "contact" if G @ y[:6] >= 0.0 else "separated"
        bounds = [*self.boundaries(t_end), t_end]
        t = 0.0
        for tb in bounds:
            seg = self.segment(t, tb)
            self.enter_segment(seg, y)
            while t < tb:
                t, y = self.integrate(seg, t, tb, y)
        return {"time": grid, **self.rec}

    def enter_segment(self, seg: Segment, y: np.ndarray) -> None:
        """Pairs that left contact slip again; every slipping pair takes the direction of its
        sliding velocity (a pair entering contact, Eq. (12))."""
        on = np.zeros(self.d.n_pairs, dtype=bool)
        on[seg.pairs] = True
        self.stuck &= on
        if self.friction == "nominal":
            nominal = self.nominal_at_a + self.dnominal_dxi * (seg.xi0 + self.vs * 1e-12)
            self.dirs[seg.pairs] = np.sign(nominal)
        elif self.friction == "stick_slip" and self.state == "contact":
            for i, j in enumerate(seg.pairs):
                v = self.sliding(seg.t0, y, seg, i)
                if not self.stuck[j] and v != 0.0:
                    self.dirs[j] = np.sign(v)

    def integrate(self, seg: Segment, t: float, tb: float, y: np.ndarray):
        """One `solve_ivp` call in the current state from ``t`` to ``tb`` (s) or the first
        event; record the grid points it passed; apply the switch. Returns the new (t, y)."""
        dirs = self.dirs[seg.pairs].tolist()
        held = np.flatnonzero(self.stuck[seg.pairs])
        # two pairs cannot stick at once: their sliding velocities differ by the constant
        # dnominal_dxi * pb, so both are never zero (and `holding_force` is scalar)
        stuck = int(held[0]) if len(held) else -1
        if self.state == "separated":
            fun = self.separated_rhs()
        else:
            fun = self.contact_rhs(seg, dirs, stuck)
        events = self.events(seg, self.state, dirs, stuck)
        # released at once: a boundary can leave a stuck pair with too little normal force
        if stuck >= 0 and self.state != "separated" and events[1 + stuck](t, y) < 0.0:
            return t, self.switch(seg, t, y, 1 + stuck)
        grid = self.grid
        ts = grid[np.searchsorted(grid, t):np.searchsorted(grid, tb)]
        # t_eval decides which states come back: the grid points, and the end of the span
        sol = solve_ivp(fun, (t, tb), y, method=self.method, t_eval=np.r_[ts, tb],
                        events=events, rtol=self.rtol, atol=self.atol)
        if sol.status == -1:
            raise ArithmeticError(f"solve_ivp failed at t = {sol.t[-1]:.9g} s: {sol.message}")
        self.record(seg, sol.t, sol.y)
        hit = [i for i, te in enumerate(sol.t_events) if len(te)]
        if not hit:
            return tb, sol.y[:, -1]
        i = hit[0]
        te, ye = float(sol.t_events[i][0]), sol.y_events[i][0]
        self.count_event(te)
        return te, self.switch(seg, te, ye, i)

    def count_event(self, te: float) -> None:
        """Count an event at ``te`` (s); stop a run whose switches chatter at one instant."""
        self.n_events += 1
        if te == getattr(self, "_last_te", None):
            self._same += 1
            if self._same > MAX_EVENTS_AT_ONE_INSTANT:
                raise RuntimeError(f"switches chatter at t = {te:.9g} s (a stall)")
        else:
            self._last_te, self._same = te, 0

    def switch(self, seg: Segment, t: float, y: np.ndarray, i: int) -> np.ndarray:
        """Apply event ``i`` (0: contact/separation, then one per pair in contact)."""
        y = y.copy()
        if i == 0:
            if self.state == "contact":
                self.state = "separated"
                self.stuck[:] = False
            else:
                self.state = "contact"
                self.enter_segment(seg, y)
            return y
        j = int(seg.pairs[i - 1])
        dirs = self.dirs[seg.pairs].tolist()
        if self.stuck[j]:  # Eq. (14) violated: slip in the direction of the static friction
            lam, _ = self.static_friction(seg, dirs, i - 1, t, y)
            self.stuck[j], self.dirs[j] = False, np.sign(lam)
            return y
        if self.stuck[seg.pairs].any():
            raise RuntimeError(f"a second pair sticks at t = {t:.9g} s (see `integrate`)")
        # the sliding velocity reversed: can static friction hold it?
        lam, normal = self.static_friction(seg, dirs, i - 1, t, y)
        if abs(lam) <= self.d.mu * abs(normal):
            self.stuck[j] = True
            y[9] += self.sliding(t, y, seg, i - 1)  # the stuck surfaces share x', Eq. (18)
        else:
            self.dirs[j] = np.sign(lam)
        return y

    def record(self, seg: Segment, ts: np.ndarray, ys: np.ndarray) -> None:
        """DTE (m) and mesh force (N) at the grid points of one `solve_ivp` call (first one
        wins), all points of the call at once."""
        if len(ts) == 0:  # an event came before the first point asked for
            return
        grid, dte = self.grid, self.rec["dte"]
        step = grid[1] - grid[0] if len(grid) > 1 else 1.0
        k = np.minimum(np.rint(ts / step).astype(np.intp), len(grid) - 1)
        on = (np.abs(ts - grid[k]) <= 1e-9 * step) & np.isnan(dte[k])
        k, ts, delta = k[on], ts[on], G @ ys[:6, on]
        dte[k] = delta
        if self.state == "separated":
            self.rec["mesh_force"][k] = 0.0
        else:
            xi = seg.xi0[None, :] + self.vs * (ts - seg.t0)[:, None]
            self.rec["mesh_force"][k] = self.stiffness(xi).sum(axis=1) * delta


@dataclass(frozen=True)
class Segment:
    """Between two known boundaries: start time (s), pairs in contact, their positions then
    (m)."""

    t0: float
    pairs: np.ndarray
    xi0: np.ndarray


def compare_with_fast(friction: str, t_end: float, rtol: float, method: str = "DOP853",
                      dt: float = 1e-4, ref_rtol: float = 1e-12,
                      stiffness: str = "potential_energy", torque: float = 3900.0,
                      rpm: float = 100.0) -> dict:
    """Run the plain implementation and the fast engine (at ``ref_rtol``) from the same
    static start; their largest DTE and mesh-force differences relative to the fast
    engine's largest magnitude, and the plain run's wall time (s) per simulated second.

    ``t_end``, ``dt`` in s, ``torque`` in N.m, ``rpm`` in r/min; the model's construction
    is not timed.
    """
    from gearpair.effects import Effects, StiffnessSpec
    from gearpair.results import simulate

    fx = Effects(friction=friction, stiffness=StiffnessSpec(stiffness))
    ref = simulate(engine="fast", effects=fx, t_end=t_end, dt=dt, rtol=ref_rtol,
                   torque=torque, speed=rpm * math.pi / 30.0)
    plain = PlainGearPair(friction, rtol, method, torque, rpm, stiffness=stiffness)
    t0 = time.perf_counter()
    got = plain.simulate(t_end, dt)
    wall = time.perf_counter() - t0
    out = {"friction": friction, "stiffness": stiffness, "rtol": rtol, "method": method,
           "t_end": t_end, "wall_per_sim_s": wall / t_end, "events": plain.n_events}
    for name in ("dte", "mesh_force"):
        r = np.asarray(ref[name], dtype=float)
        out["diff_" + name] = float(np.max(np.abs(got[name] - r)) / np.max(np.abs(r)))
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line: compare with the fast engine, one line per friction law."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=0.02, help="simulated time (s)")
    ap.add_argument("--rtol", type=float, default=1e-9)
    ap.add_argument("--method", default="DOP853", help="a solve_ivp method")
    ap.add_argument("--stiffness", choices=STIFFNESS, default="potential_energy")
    ap.add_argument("--friction", choices=FRICTION, action="append",
                    help="friction law (repeat for several; default all)")
    ap.add_argument("--torque", type=float, default=3900.0, help="N.m")
    ap.add_argument("--rpm", type=float, default=100.0, help="speed of gear 1 (r/min)")
    args = ap.parse_args(argv)
    for friction in args.friction or FRICTION:
        c = compare_with_fast(friction, args.t_end, args.rtol, args.method,
                              stiffness=args.stiffness, torque=args.torque, rpm=args.rpm)
        print(f"{friction:10s} {args.stiffness} {args.method} rtol {args.rtol:g}: "
              f"{c['wall_per_sim_s']:.2f} s per simulated s, {c['events']} events; against "
              f"the fast engine: DTE {c['diff_dte']:.1e}, mesh force "
              f"{c['diff_mesh_force']:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
