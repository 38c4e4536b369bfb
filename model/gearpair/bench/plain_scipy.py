"""The gear pair as a scipy user would write it: what `gearpair bench` compares the fast core with.

The same model as the package (Xun, Dai, Wang 2023: 6 DOF, Eqs. (1)-(25); potential-energy
mesh stiffness, tooth separation, Coulomb friction in the nominal direction or stick-slip by
Eq. (14)), written the plain way: one vectorized numpy right-hand side per contact state
(slip, stick, separated), `scipy.integrate.solve_ivp` with terminal events for the switches,
and a restart after each event with the new state. It takes from `gearpair` only data: the
Table 1 parameters, the derived geometry and the per-pair stiffness spline (so that both
sides integrate the same equations); nothing of the package's engines or switching code.

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
G = np.array([0.0, 1.0, 1.0, 0.0, -1.0, 1.0])  # delta = y1 - y2 + u1 + u2, Eq. (3)
A_SLIDE = np.array([1.0, 0.0, 0.0, -1.0, 0.0, 0.0])  # d v_j / d q', Eq. (12)
MAX_EVENTS_AT_ONE_INSTANT = 50


@dataclass(frozen=True)
class Data:
    """Table 1 gear pair reduced to numbers (SI): masses, supports, geometry, stiffness."""

    minv: np.ndarray   # diagonal of M^-1, Eq. (5)
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
    knots: np.ndarray  # stiffness spline knots (m) and coefficients per interval (N/m ...)
    coef: np.ndarray

    @classmethod
    def table1(cls) -> Data:
        from gearpair.effects import StiffnessSpec
        from gearpair.geometry import Geometry
        from gearpair.params import GearParams
        from gearpair.stiffness import MeshStiffness

        p = GearParams()
        g = Geometry.from_params(p)
        k = MeshStiffness.build(p, g, StiffnessSpec("potential_energy"))
        return cls(
            minv=1.0 / np.array([p.m1, p.m1, p.mu1, p.m2, p.m2, p.mu2]),
            c=np.array([p.cb1, p.cb1, p.cr1, p.cb2, p.cb2, p.cr2]),
            kb=np.array([p.kb1, p.kb1, p.kr1, p.kb2, p.kb2, p.kr2]),
            rb1=p.rb1, rb2=p.rb2, ratio=p.ratio, cm=p.cm, mu=p.mu, pb=g.base_pitch,
            length=g.path_length, s1a=g.s1a, s1s2=g.s1s2, xi_pitch=g.xi_pitch,
            n_pairs=g.n_pairs, knots=k.xi, coef=k.cubic)


class PlainGearPair:
    """The model integrated by `solve_ivp`, one contact state at a time.

    Parameters
    ----------
    friction : "off", "nominal" (Coulomb friction in the direction of the nominal sliding
        velocity) or "stick_slip" (sign law with stick by Eq. (14))
    rtol : relative tolerance; atol is rtol times 1e-5 m for positions, 1e-3 m/s for rates
    method : any `solve_ivp` method
    torque : driving torque (N.m); rpm : speed of gear 1 (r/min)
    """

    def __init__(self, friction: str = "stick_slip", rtol: float = 1e-9,
                 method: str = "DOP853", torque: float = 3900.0, rpm: float = 100.0,
                 data: Data | None = None) -> None:
        if friction not in FRICTION:
            raise ValueError(f"friction = {friction!r}; choose one of {', '.join(FRICTION)}")
        self.d = data or Data.table1()
        self.friction, self.rtol, self.method = friction, rtol, method
        self.atol = rtol * np.r_[np.full(6, 1e-5), np.full(6, 1e-3)]
        self.torque, self.speed = torque, rpm * math.pi / 30.0
        self.vs = self.d.rb1 * self.speed  # contact points move along the LOA (m/s)
        self.n_events = 0
        d = self.d
        self.h, self.last = d.knots[1] - d.knots[0], len(d.knots) - 2
        self.load = np.array([0.0, 0.0, torque / d.rb1, 0.0, 0.0, 0.0])  # Eq. (10)
        # w_j and the nominal sliding velocity are affine in the position xi_j
        self.w_at_a = np.array([-1.0, 0.0, d.s1a / d.rb1, 1.0, 0.0, (d.s1s2 - d.s1a) / d.rb2])
        self.dw_dxi = np.array([0.0, 0.0, 1.0 / d.rb1, 0.0, 0.0, -1.0 / d.rb2])
        self.nominal_at_a = self.speed * (d.ratio * (d.s1s2 - d.s1a) - d.s1a)
        self.dnominal_dxi = -self.speed * (1.0 + d.ratio)
        self.c0, self.c1, self.c2, self.c3 = (np.ascontiguousarray(d.coef[:, j])
                                              for j in range(4))
        # y' = A y + b + (mesh spring and friction): A holds d q/dt = q', the supports and
        # the mesh damper (it acts while the teeth touch), Eqs. (4)-(5)
        gg = np.outer(G, G)
        self.a_contact = np.zeros((12, 12))
        self.a_contact[:6, 6:] = np.eye(6)
        self.a_contact[6:, :6] = -d.minv[:, None] * np.diag(d.kb)
        self.a_contact[6:, 6:] = -d.minv[:, None] * (np.diag(d.c) + d.cm * gg)
        self.b = np.r_[np.zeros(6), d.minv * self.load]
        self.mesh_dir = np.r_[np.zeros(6), -d.minv * G]  # y'' per newton of mesh force
        self.fric_at_a = np.r_[np.zeros(6), d.minv * self.w_at_a]  # y'' per newton of friction
        self.fric_dxi = np.r_[np.zeros(6), d.minv * self.dw_dxi]   # ... its change with xi

    # -- the model at one instant ------------------------------------------------------------
    def stiffness(self, xi: np.ndarray) -> np.ndarray:
        """Per-pair mesh stiffness (N/m) at positions ``xi`` from A (cubic spline)."""
        # positions stay in [0, L] within a segment; L itself falls on the last interval
        i = np.minimum((xi * (1.0 / self.h)).astype(np.intp), self.last)
        x = xi - self.d.knots[i]
        return ((self.c3[i] * x + self.c2[i]) * x + self.c1[i]) * x + self.c0[i]

    def arms(self, xi: np.ndarray):
        """Friction directions w_j (Eq. (9)) and nominal sliding velocities (Eq. (12))."""
        w = self.w_at_a + np.outer(xi, self.dw_dxi)
        return w, self.nominal_at_a + self.dnominal_dxi * xi

    def free_forces(self, q, qd) -> np.ndarray:
        """Load, support springs and dampers, Eqs. (4), (10)."""
        return self.load - self.d.c * qd - self.d.kb * q

    def contact_forces(self, t, y, seg, dirs):
        """Forces in contact with the pairs sliding in directions ``dirs`` (Eqs. (4)-(11)):
        (generalized force, normal force per pair, friction directions, sliding velocities)."""
        q, qd = y[:6], y[6:]
        xi = seg.xi0 + self.vs * (t - seg.t0)
        k = self.stiffness(xi)
        delta = q[1] - q[4] + q[2] + q[5]
        ddelta = qd[1] - qd[4] + qd[2] + qd[5]
        f = self.free_forces(q, qd) - (k.sum() * delta + self.d.cm * ddelta) * G
        normal = k * delta
        w, nominal = self.arms(xi)
        if self.friction != "off":
            f += (self.d.mu * np.abs(normal) * dirs) @ w
        return f, normal, w, nominal + qd[0] - qd[3]

    def rhs_separated(self, t, y):
        """Teeth apart: no mesh force, no mesh damping, no friction (Eq. (8))."""
        return np.concatenate((y[6:], self.d.minv * self.free_forces(y[:6], y[6:])))

    def rhs_slip(self, t, y, seg, dirs):
        """Every pair in contact slides (sign law or nominal direction): the linear part as
        one matrix product, the mesh spring k(t) delta and the friction forces added."""
        xi = seg.xi0 + self.vs * (t - seg.t0)
        k = self.stiffness(xi)
        delta = y[1] - y[4] + y[2] + y[5]
        out = self.a_contact @ y + self.b + (k.sum() * delta) * self.mesh_dir
        if self.friction != "off":
            # sum_j f_j w_j with w_j affine in xi_j: two terms, whatever the number of pairs
            f = k * dirs * (self.d.mu * abs(delta))
            out += f.sum() * self.fric_at_a + (f @ xi) * self.fric_dxi
        return out

    def static_friction(self, f, w, stuck):
        """Static friction (N) of the stuck pairs holding d v_j/dt = 0 (Eqs. (15), (18),
        exact tie: the nominal sliding velocity changes at -(Omega1 + Omega2) rb1 Omega1)."""
        ws = w[stuck]
        a = np.tile(A_SLIDE, (len(ws), 1)) * self.d.minv
        rate = -(1.0 + self.d.ratio) * self.vs * self.speed
        return np.linalg.solve(a @ ws.T, -(rate + a @ f))

    def rhs_stick(self, t, y, seg, dirs, stuck):
        """Pairs in ``stuck`` are held by static friction (Lagrange multipliers)."""
        f, _, w, _ = self.contact_forces(t, y, seg, np.where(stuck, 0.0, dirs))
        f = f + self.static_friction(f, w, stuck) @ w[stuck]
        return np.concatenate((y[6:], self.d.minv * f))

    # -- events: positive while the state holds, falling through zero when it ends ----------
    def events(self, seg, state, dirs, stuck):
        """Terminal event functions of a state: contact (delta) or separation (-delta), then
        per pair in contact its stick margin (stuck) or d v (slipping in direction d)."""
        evs = []
        if state == "separated":
            evs.append(lambda t, y: -(G @ y[:6]))
        else:
            evs.append(lambda t, y: G @ y[:6])
        if state != "separated" and self.friction == "stick_slip":
            for i in range(len(seg.pairs)):
                if stuck[i]:
                    evs.append(lambda t, y, i=i: self.stick_margin(t, y, seg, dirs, stuck, i))
                else:
                    evs.append(lambda t, y, i=i: dirs[i] * self.sliding(t, y, seg, i))
        for e in evs:
            e.terminal, e.direction = True, -1
        return evs

    def sliding(self, t, y, seg, i) -> float:
        """Sliding velocity of pair i in contact (m/s), Eq. (12)."""
        xi = seg.xi0[i] + self.vs * (t - seg.t0)
        return self.nominal_at_a + self.dnominal_dxi * xi + y[6] - y[9]

    def stick_margin(self, t, y, seg, dirs, stuck, i):
        """mu |N_i| - |lambda_i| of stuck pair i (Eq. (14))."""
        f, normal, w, _ = self.contact_forces(t, y, seg, np.where(stuck, 0.0, dirs))
        lam = self.static_friction(f, w, stuck)
        return self.d.mu * abs(normal[i]) - abs(lam[int(np.count_nonzero(stuck[:i]))])

    # -- the run -----------------------------------------------------------------------------
    def boundaries(self, t_end: float) -> np.ndarray:
        """Instants in (0, t_end) where a pair enters or leaves contact (or, for nominal
        friction, passes the pitch point): mesh travel k pb + offset."""
        d = self.d
        offsets = [0.0, math.fmod(d.length, d.pb)]
        if self.friction == "nominal":
            offsets.append(math.fmod(d.xi_pitch, d.pb))
        s_end = self.vs * t_end
        out = [(k * d.pb + o) / self.vs for o in offsets
               for k in range(math.ceil(s_end / d.pb) + 1) if 0.0 < k * d.pb + o < s_end]
        return np.unique(out)

    def segment(self, ta: float, tb: float):
        """Pairs in contact between two boundaries, and their positions at ``ta``."""
        d = self.d
        s_mid = self.vs * 0.5 * (ta + tb)
        xi_mid = np.mod(s_mid + np.arange(d.n_pairs) * d.pb, d.n_pairs * d.pb)
        pairs = np.flatnonzero(xi_mid < d.length)
        return Segment(ta, pairs, xi_mid[pairs] - self.vs * (0.5 * (tb - ta)))

    def simulate(self, t_end: float, dt: float = 1e-4) -> dict:
        """Run from the static equilibrium at t = 0 and record every ``dt``: time, DTE (m),
        mesh force (N)."""
        n = self.d.n_pairs
        grid = np.arange(int(round(t_end / dt)) + 1) * dt
        self.rec = {"dte": np.full(len(grid), np.nan), "mesh_force": np.full(len(grid), np.nan)}
        self.grid = grid
        seg = self.segment(0.0, min(t_end, 1e-9))
        k0 = self.stiffness(seg.xi0).sum()
        y = np.zeros(12)
        y[:6] = np.linalg.solve(np.diag(self.d.kb) + k0 * np.outer(G, G),
                                self.free_forces(np.zeros(6), np.zeros(6)))
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

    def enter_segment(self, seg, y) -> None:
        """Pairs that left contact slip again; every slipping pair takes the direction of its
        sliding velocity (a pair entering contact, Eq. (12))."""
        on = np.zeros(self.d.n_pairs, dtype=bool)
        on[seg.pairs] = True
        self.stuck &= on
        if self.friction == "nominal":
            _, nominal = self.arms(seg.xi0 + self.vs * 1e-12)
            self.dirs[seg.pairs] = np.sign(nominal)
        elif self.friction == "stick_slip" and self.state == "contact":
            v = self.contact_forces(seg.t0, y, seg, self.dirs[seg.pairs])[3]
            for i, j in enumerate(seg.pairs):
                if not self.stuck[j] and v[i] != 0.0:
                    self.dirs[j] = np.sign(v[i])

    def integrate(self, seg, t, tb, y):
        """One `solve_ivp` call in the current state from ``t`` to ``tb`` or the first event;
        record the grid points it passed; apply the switch. Returns the new (t, y)."""
        dirs, stuck = self.dirs[seg.pairs].copy(), self.stuck[seg.pairs].copy()
        if self.state == "separated":
            fun = self.rhs_separated
        elif stuck.any():
            def fun(t, y):
                return self.rhs_stick(t, y, seg, dirs, stuck)
        else:
            def fun(t, y):
                return self.rhs_slip(t, y, seg, dirs)
        events = self.events(seg, self.state, dirs, stuck)
        # released at once: a boundary can leave a stuck pair with too little normal force
        if self.state != "separated" and self.friction == "stick_slip":
            for i, e in enumerate(events[1:]):
                if stuck[i] and e(t, y) < 0.0:
                    return t, self.switch(seg, t, y, 1 + i)
        ts = self.grid[(self.grid >= t) & (self.grid < tb)]
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
        self.n_events += 1
        if te == getattr(self, "_last_te", None):
            self._same += 1
            if self._same > MAX_EVENTS_AT_ONE_INSTANT:
                raise RuntimeError(f"switches chatter at t = {te:.9g} s (a stall)")
        else:
            self._last_te, self._same = te, 0

    def switch(self, seg, t, y, i) -> np.ndarray:
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
        dirs, stuck = self.dirs[seg.pairs], self.stuck[seg.pairs]
        f, normal, w, v = self.contact_forces(t, y, seg, np.where(stuck, 0.0, dirs))
        if self.stuck[j]:  # Eq. (14) violated: slip in the direction of the static friction
            lam = self.static_friction(f, w, stuck)[int(np.count_nonzero(stuck[:i - 1]))]
            self.stuck[j], self.dirs[j] = False, np.sign(lam)
            return y
        trial = stuck.copy()
        trial[i - 1] = True  # the sliding velocity reversed: can static friction hold it?
        f, normal, w, _ = self.contact_forces(t, y, seg, np.where(trial, 0.0, dirs))
        lam = self.static_friction(f, w, trial)[int(np.count_nonzero(trial[:i - 1]))]
        if abs(lam) <= self.d.mu * abs(normal[i - 1]):
            self.stuck[j] = True
            y[9] += v[i - 1]  # the stuck surfaces share x', Eq. (18): v_j = 0 exactly
        else:
            self.dirs[j] = np.sign(lam)
        return y

    def record(self, seg, ts, ys) -> None:
        """DTE and mesh force at the grid points of one `solve_ivp` call (first one wins)."""
        if len(ts) == 0:  # an event came before the first point asked for
            return
        step = self.grid[1] - self.grid[0] if len(self.grid) > 1 else 1.0
        for t, y in zip(ts, ys.T, strict=True):
            k = int(round(t / step))
            if k >= len(self.grid) or abs(t - self.grid[k]) > 1e-9 * step \
                    or not np.isnan(self.rec["dte"][k]):
                continue
            delta = G @ y[:6]
            km = self.stiffness(seg.xi0 + self.vs * (t - seg.t0)).sum()
            self.rec["dte"][k] = delta
            self.rec["mesh_force"][k] = 0.0 if self.state == "separated" else km * delta


@dataclass(frozen=True)
class Segment:
    """Between two known boundaries: start time, pairs in contact, their positions then."""

    t0: float
    pairs: np.ndarray
    xi0: np.ndarray


def compare_with_fast(friction: str, t_end: float, rtol: float, method: str = "DOP853",
                      dt: float = 1e-4, ref_rtol: float = 1e-12) -> dict:
    """Run the plain implementation and the fast engine (at ``ref_rtol``) from the same
    static start; their largest DTE and mesh-force differences relative to the fast
    engine's largest magnitude, and the plain run's wall time per simulated second."""
    from gearpair.effects import Effects
    from gearpair.results import simulate

    fx = Effects(friction=friction)
    ref = simulate(engine="fast", effects=fx, t_end=t_end, dt=dt, rtol=ref_rtol)
    plain = PlainGearPair(friction, rtol, method)
    t0 = time.perf_counter()
    got = plain.simulate(t_end, dt)
    wall = time.perf_counter() - t0
    out = {"friction": friction, "rtol": rtol, "method": method, "t_end": t_end,
           "wall_per_sim_s": wall / t_end, "events": plain.n_events}
    for name in ("dte", "mesh_force"):
        r = np.asarray(ref[name], dtype=float)
        out["diff_" + name] = float(np.max(np.abs(got[name] - r)) / np.max(np.abs(r)))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=0.02)
    ap.add_argument("--rtol", type=float, default=1e-9)
    ap.add_argument("--method", default="DOP853")
    args = ap.parse_args(argv)
    for friction in FRICTION:
        c = compare_with_fast(friction, args.t_end, args.rtol, args.method)
        print(f"{friction:10s} {args.method} rtol {args.rtol:g}: {c['wall_per_sim_s']:.2f} s "
              f"per simulated s, {c['events']} events; against the fast engine: DTE "
              f"{c['diff_dte']:.1e}, mesh force {c['diff_mesh_force']:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
