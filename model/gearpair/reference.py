"""The reference engine: scipy's ODE solvers, written to be checked against the paper.

How a step is taken: a scipy `OdeSolver` (DOP853 by default; RK45, Radau, LSODA selectable)
integrates the equations of one contact state (`equations.evaluate`). When the state changes:

- *known* discontinuities, where a tooth pair enters or leaves the path of contact (and the
  pitch point for the nominal friction law), are segment boundaries computed from the mesh
  travel, never events to hunt;
- *unknown* switches (`switching`) are located on the solver's dense output. scipy's own event
  handling compares signs only at step ends and silently loses a crossing that begins and
  ends inside one step (docs/model.md); here every accepted step is also sampled at
  ``n_samples`` interior points and the first fall through zero is refined with Brent's
  method, and the step is bounded by ``max_step``.

This is the yardstick the FMU and the fast engine are verified against, not the fast path.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import DOP853, LSODA, RK23, RK45, Radau
from scipy.optimize import brentq, minimize_scalar

from .effects import Effects
from .engine import (
    CONTACT_BACK,
    CONTACT_SEPARATED,
    CONTACT_SLIP,
    CONTACT_STICK,
    G_START,
    Engine,
    Outputs,
    RunFailure,
    StepSummary,
    check_inputs,
    run_failure_message,
)
from .equations import U1, U2, G, Model, evaluate
from .params import GearParams, check_rtol
from .switching import (
    Mode,
    event_labels,
    event_values,
    settle_directions,
    speed_change,
    switch,
)

METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853, "Radau": Radau, "LSODA": LSODA}
N_Q = 6
N_E = 4  # energy quadratures: input work, damping loss, friction work, parametric work
A, AD = 16, 17  # load-shaft end a (m, u2 coordinates) and its rate a' (m/s, held per step)
N_Y = 2 * N_Q + N_E + 2
# Gauss-Legendre nodes and weights on [0, 1] (3 points, exact to degree 5): the time integral
# of the mesh force over each solver step on its dense output (StepSummary.mesh_force_mean)
_GL3_X = np.array([0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6)])
_GL3_W = np.array([5.0, 8.0, 5.0]) / 18.0
# Typical magnitudes, for absolute tolerances: deflections ~10 um, velocities ~1 mm/s... 1 m/s
_SCALE = np.r_[np.full(6, 1e-5), np.full(6, 1e-3), np.full(N_E, 1.0), 1e-5, 1e-3]


def _first_positive(g, lo: float, hi: float) -> float | None:
    """A point of (lo, hi) where g > 0, halving towards lo, or None: a piece that starts
    with its flank function at zero, taken as positive (`_start_flanks`), has a root at its
    start, and the fall to locate is the next one."""
    for _ in range(200):
        hi = 0.5 * (lo + hi)
        if not lo < hi:
            return None
        if g(hi) > 0.0:
            return hi
    return None


def _past_root(g, lo: float, hi: float) -> float:
    """The event time of a function g that falls from g(lo) > 0 to g(hi) <= 0: a point at
    most a few root tolerances past its root, where g <= 0 already (as the fast engine's
    right end of the bracket). brentq's root may lie on either side, and a state left on
    the old side starts the next piece with its new function below zero (issue 38)."""
    te = brentq(g, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    step = 4.0 * (1e-15 + 4 * np.finfo(float).eps * abs(te))
    if g(te) <= 0.0:
        return te
    lo = te
    c = te + step
    if c < hi and g(c) <= 0.0:
        return c
    while hi - lo > step:  # bisect, keeping the end where g has fallen
        mid = 0.5 * (lo + hi)
        if g(mid) <= 0.0:
            hi = mid
        else:
            lo = mid
    return hi


class ReferenceEngine(Engine):
    """scipy-based engine implementing the `Engine` contract.

    Parameters
    ----------
    params, effects : the gear pair and the effects to include
    rtol : relative tolerance of the ODE solver
    atol : absolute tolerance; default ``rtol`` times typical magnitudes of each state
    method : scipy solver name (RK45, DOP853, Radau, LSODA, RK23)
    max_step : largest solver step (s); default a tenth of the shortest natural period, so
        that no switch can hide inside a step between two dense samples
    n_samples : interior dense-output samples per step scanned for sign changes
    max_events : bound on switches per `advance` call; more raises RuntimeError (a stall)
    """

    def __init__(self, params: GearParams | None = None, effects: Effects | None = None,
                 rtol: float = 1e-8, atol: float | None = None, method: str = "DOP853",
                 max_step: float | None = None, n_samples: int = 8,
                 max_events: int = 100_000) -> None:
        if method not in METHODS:
            raise ValueError(f"method = {method!r}; choose one of {', '.join(METHODS)}")
        check_rtol(rtol)
        self.model = Model.build(params, effects)
        self._dte_bound = self.model.dte_bound()
        self._prev_active = None  # pairs in contact in the last segment (set by reset)
        self._released = None  # (pair, time) of the last release of a stick
        self.rtol = rtol
        self.atol = _SCALE * (rtol if atol is None else atol / rtol * rtol)
        if atol is not None:
            self.atol = np.full(N_Y, atol)
        self.method = method
        if max_step is None:
            from .modal import natural_frequencies

            fmax = natural_frequencies(self.model, "slip")[-1]
            max_step = 0.5 / fmax
        self.max_step = max_step
        self.n_samples = n_samples
        self.max_events = max_events
        self._h = None
        self.reset()

    # -- contract ----------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.t

    def reset(self, t0: float = 0.0, torque: float = 0.0, speed: float = 0.0,
              static: bool = True) -> None:
        check_inputs(torque, speed)
        m = self.model
        n = m.geom.n_pairs
        self.t = float(t0)
        self.s = 0.0  # mesh travel (m): pair 0 enters contact at t0
        self.torque, self.speed = float(torque), float(speed)
        self.y = np.zeros(N_Y)
        active, _, _, _, k = m.contact(self.s)
        if static and torque != 0.0:
            self.y[:N_Q] = m.static_deflection(torque, float(k.sum()))
        code = m.contact_code(float(G @ self.y[:N_Q]))
        self.mode = Mode(code != 0, np.ones(n), np.zeros(n, dtype=bool), code == 2)
        self.mode, qd = settle_directions(m, self.s, self.y[:N_Q], self.y[N_Q:2 * N_Q],
                                          self.torque, self.speed, active, self.mode)
        self.t_stick = 0.0
        self.t_sep = 0.0
        self.t_back = 0.0
        self.n_events_total = 0
        self._last = None
        self._h = None
        self._prev_active = active

    def get_state(self) -> dict:
        return {
            "t": self.t, "s": self.s, "y": self.y.copy(), "torque": self.torque,
            "speed": self.speed, "separated": self.mode.separated, "back": self.mode.back,
            "dirs": self.mode.dirs.copy(), "stuck": self.mode.stuck.copy(),
            "t_stick": self.t_stick, "t_sep": self.t_sep, "t_back": self.t_back,
            "n_events_total": self.n_events_total,
            "h": self._h, "last": self._last,
            "prev_active": None if self._prev_active is None else np.array(self._prev_active),
        }

    def set_state(self, state: dict) -> None:
        self.t, self.s = float(state["t"]), float(state["s"])
        self.y = np.array(state["y"], dtype=float)
        self.torque, self.speed = float(state["torque"]), float(state["speed"])
        self.mode = Mode(bool(state["separated"]), np.array(state["dirs"], dtype=float),
                         np.array(state["stuck"], dtype=bool), bool(state.get("back", False)))
        self.t_stick, self.t_sep = float(state["t_stick"]), float(state["t_sep"])
        self.t_back = float(state.get("t_back", 0.0))
        self.n_events_total = int(state["n_events_total"])
        self._h = state["h"]
        self._last = state["last"]
        pa = state.get("prev_active")
        self._prev_active = None if pa is None else np.asarray(pa, dtype=np.int64)

    # -- integration -------------------------------------------------------------------------
    def _travel(self, t: float) -> float:
        return self.s + self.model.p.rb1 * self.speed * (t - self.t)

    def _rhs(self, active, mode: Mode, t0: float, s0: float):
        m, torque, speed = self.model, self.torque, self.speed
        dirs, stuck = mode.dirs[active], mode.stuck[active]
        rb1 = m.rb1
        cm = m.cm
        c_diag = m.c_diag
        kr2, cr2 = m.p.kr2, m.p.cr2

        varying = m.stiff.kind not in ("constant", "rectangular")

        def fun(t, y):
            q, qd = y[:N_Q], y[N_Q:2 * N_Q]
            s = s0 + rb1 * speed * (t - t0)
            a, ad = y[A], y[AD]
            ev = evaluate(m, s, q, qd, torque, speed, active, mode.separated, dirs, stuck,
                          mode.back, (a, ad))
            dkm = float(m.stiff.slope(ev.xi, len(active)).sum()) * rb1 * speed \
                if varying else 0.0
            out = np.empty_like(y)
            out[:N_Q] = qd
            out[N_Q:2 * N_Q] = ev.qdd
            # the load-shaft end does work -(kr2 (u2 - a) + cr2 (u2' - a')) a'
            out[12] = torque / rb1 * qd[U1] - (kr2 * (q[U2] - a) + cr2 * (qd[U2] - ad)) * ad
            out[13] = c_diag @ (qd * qd) + ev.theta * cm * ev.ddelta**2 \
                + cr2 * ((qd[U2] - ad) ** 2 - qd[U2] ** 2)
            out[14] = float(ev.friction @ (ev.w @ qd))
            out[15] = 0.5 * dkm * ev.compression**2
            out[A] = ad
            out[AD] = 0.0
            return out

        return fun

    def _eval_at(self, t, y, active, mode, t0, s0):
        m = self.model
        s = s0 + m.p.rb1 * self.speed * (t - t0)
        return evaluate(m, s, y[:N_Q], y[N_Q:2 * N_Q], self.torque, self.speed, active,
                        mode.separated, mode.dirs[active], mode.stuck[active], mode.back,
                        (y[A], y[AD]))

    def advance_values(self, t_end: float, torque: float, speed: float,
                       load_speed: float | None = None) -> StepSummary:
        fx = self.model.effects
        if speed == 0.0 and fx.friction == "stick_slip" and fx.sliding == "paper":
            # Both pairs slide at v = 0 and, with Eq. (12), every pair's sliding velocity
            # moves only with x1' - x2': their stick constraints coincide and the static
            # friction of two stuck pairs is undetermined (a singular system here; the fast
            # engine lets the second pair slip at v = 0 instead).
            raise ValueError(
                "speed = 0 (standstill) with friction = 'stick_slip' and sliding = 'paper': "
                "the reference engine cannot run it (the stick constraints of the pairs in "
                "mesh coincide); use the fast engine (the default) or sliding = 'full'")
        t_start = self.t
        if not (t_end > t_start):
            raise ValueError(f"t_end = {t_end!r} must be after the current time {t_start!r}")
        m = self.model
        if float(speed) != self.speed:
            active, _, _, _, _ = m.contact(self.s, self._prev_active)
            self.mode, qd = speed_change(m, self.s, self.y[:N_Q], self.y[N_Q:2 * N_Q],
                                         float(torque), float(speed), active, self.mode,
                                         float(t_end) - t_start)
            self.y = self.y.copy()
            qd0 = self.y[N_Q:2 * N_Q]
            # a friction impulse that keeps a stick changes the kinetic energy: friction work
            self.y[14] += 0.5 * float(qd @ m.M @ qd - qd0 @ m.M @ qd0)
            self.y[N_Q:2 * N_Q] = qd
        self.torque, self.speed = float(torque), float(speed)
        self.y = self.y.copy()
        self.y[AD] = 0.0 if load_speed is None else \
            -m.p.rb2 * (float(load_speed) - float(speed) * m.p.ratio)
        rb1 = m.p.rb1
        extra = (m.geom.xi_pitch,) if m.effects.friction == "nominal" else ()
        s_end = self._travel(t_end)
        # boundaries a rounding error past the end of the step count as inside it (the step
        # then reports the set after them, as the fast engine)
        s_lim = s_end + math.copysign(abs(rb1 * speed) * 16 * np.finfo(float).eps
                                      * max(1.0, abs(t_end)), speed)
        bounds_s = m.geom.boundaries(self.s, s_lim, extra) if speed != 0.0 else np.zeros(0)
        t_bounds = [self.t + (b - self.s) / (rb1 * speed) for b in bounds_s] + [t_end]
        stick0, sep0, back0 = self.t_stick, self.t_sep, self.t_back
        fmax, fmin, fint = -math.inf, math.inf, 0.0
        n_ev = 0
        n_steps = 0
        for tb in t_bounds:
            tb = min(max(tb, self.t), t_end)
            s_mid = self._travel(0.5 * (self.t + tb))
            nudge = 1e-9 * m.geom.base_pitch
            if abs(s_mid - self.s) < nudge and speed != 0.0:  # zero-length: set after it
                s_mid = self.s + math.copysign(nudge, speed)
            active, _, _, _, _ = m.contact(s_mid)
            # A pair entering contact takes its slip direction from its sliding velocity.
            self.mode, qd = settle_directions(m, self.s, self.y[:N_Q], self.y[N_Q:2 * N_Q],
                                              torque, speed, active, self._entering(active))
            km_before = self._km_now(self._prev_active) if self._prev_active is not None \
                else None
            if km_before is not None:
                # Stored mesh energy jumps when a pair enters or leaves: book it as parametric.
                ev = self._eval_at(self.t, self.y, active, self.mode, self.t, self.s)
                self.y[15] += 0.5 * (ev.km - km_before) * ev.compression**2
            while self.t < tb:
                n_ev_seg, n_st, fm, fm_lo, fi = self._integrate_segment(tb, active,
                                                                        (fmax, fmin))
                n_ev += n_ev_seg
                n_steps += n_st
                fmax = max(fmax, fm)
                fmin = min(fmin, fm_lo)
                fint += fi
                if n_ev > self.max_events:
                    raise RuntimeError(
                        f"more than {self.max_events} contact switches in one step "
                        f"(t = {self.t:.9g} s): the run stalls (docs/limits.md, event-count rule)")
            self._prev_active = active
        self.t = float(t_end)
        self.n_events_total += n_ev
        h = t_end - t_start
        out = self.outputs()
        fmax = max(fmax, out.mesh_force)
        fmin = min(fmin, out.mesh_force)
        self._last = (t_start, t_end)
        return StepSummary(t_start, t_end, (self.t_stick - stick0) / h,
                           (self.t_sep - sep0) / h, fmax, n_ev, n_steps,
                           (self.t_back - back0) / h, fint / h, fmin)

    def _km_now(self, active):
        m = self.model
        _, _, _, _, k = m.contact(self.s, active)
        return float(k.sum())

    def _entering(self, active) -> Mode:
        mode = self.mode.copy()
        prev = self._prev_active
        if prev is not None:
            for j in range(len(mode.stuck)):
                if j not in active:
                    mode.stuck[j] = False
        return mode

    def _mesh_force(self, t, y, active, mode: Mode, t0, s0) -> float:
        """Elastic mesh force (N) at (t, y) in a contact state (what `evaluate` gives as
        ``mesh_force``, without the forces and accelerations)."""
        if mode.separated and not mode.back:
            return 0.0
        m = self.model
        _, _, _, _, k = m.contact(s0 + m.p.rb1 * self.speed * (t - t0), active)
        delta = float(G @ y[:N_Q])
        return float(k.sum()) * (delta + m.backlash if mode.separated else delta)

    def _mesh_force_integral(self, sol, ta, tb, active, mode, t0, s0) -> float:
        """Integral (N s) of the mesh force over [ta, tb] on the dense output ``sol``."""
        h = tb - ta
        return h * sum(w * self._mesh_force(ta + x * h, sol(ta + x * h), active, mode, t0, s0)
                       for x, w in zip(_GL3_X, _GL3_W, strict=True))

    def _step_extremes(self, force, ts, fs, fmax: float, fmin: float) -> tuple[float, float]:
        """The least and greatest mesh force over one solver step, with the running ones.

        ``ts``, ``fs``: the step's start, its dense samples and its end (or the switch that
        cut it short); ``force(t)``: the force on the step's dense output. Where the samples
        could hide a value beyond the running extremes (the highest sample within the
        largest change between neighbouring samples of them), the turn is located on the
        dense output by bounded Brent between the neighbours of that sample. So the extremes
        are the trajectory's, not the samples' (StepSummary.mesh_force_min/max).
        """
        fs = np.asarray(fs, dtype=float)
        slack = float(np.abs(np.diff(fs)).max()) if len(fs) > 1 else 0.0
        n = len(fs)
        for sgn in (1.0, -1.0):
            k = int(np.argmax(sgn * fs))
            best = sgn * fs[k]
            if best + slack > (fmax if sgn > 0 else -fmin) and n > 1:
                a, b = ts[max(k - 1, 0)], ts[min(k + 1, n - 1)]
                res = minimize_scalar(lambda t, sgn=sgn: -sgn * force(t), bounds=(a, b),
                                      method="bounded", options={"xatol": 1e-6 * (b - a)})
                best = max(best, -float(res.fun))
            if sgn > 0:
                fmax = max(fmax, best)
            else:
                fmin = min(fmin, -best)
        return fmax, fmin

    def _integrate_segment(self, tb: float, active,
                           extremes: tuple[float, float]) -> tuple[int, int, float, float, float]:
        """Integrate in one contact state from self.t towards tb; stop at the first switch.

        ``extremes``: the greatest and least mesh force of the advance so far (N), what a
        step's turn must beat to be located (`_step_extremes`). Returns (number of
        switches, solver steps, greatest and least mesh force over the piece together with
        ``extremes``, the mesh force's time integral (N s))."""
        m = self.model
        mode = self.mode
        t0, s0 = self.t, self.s
        fun = self._rhs(active, mode, t0, s0)
        labels = event_labels(m, mode, active)
        solver_cls = METHODS[self.method]
        kw = {"rtol": self.rtol, "atol": self.atol, "max_step": self.max_step}
        if self._h is not None:
            kw["first_step"] = min(self._h, tb - t0)
        solver = solver_cls(fun, t0, self.y, tb, **kw)
        fmax, fmin = extremes
        fint = 0.0

        def values(t, y):
            ev = self._eval_at(t, y, active, mode, t0, s0)
            return event_values(m, ev, mode, active), ev

        g_prev, ev0 = values(t0, self.y)
        due = self._start_flanks(g_prev, labels, ev0)
        if due is not None:
            return self._switch_now(labels[due], active, mode, ev0)
        # A known boundary can invalidate a stick at once (the entering pair takes load, so
        # mu f_mesh drops below the static friction): release it before integrating.
        for i, (kind, j) in enumerate(labels):
            if kind == "pair" and mode.stuck[j] and g_prev[i] < 0.0:
                self._released = (j, self.t)
                self.mode, qd = switch(m, labels[i], self.s, self.y[:N_Q], self.y[N_Q:2 * N_Q],
                                       self.torque, self.speed, active, mode)
                self.y = self.y.copy()
                self.y[N_Q:2 * N_Q] = qd
                return 1, 0, ev0.mesh_force, ev0.mesh_force, 0.0
        retest = False
        for i, (kind, j) in enumerate(labels):
            if kind == "pair" and not mode.stuck[j] and g_prev[i] == 0.0 \
                    and self._released != (j, self.t):  # not the pair just released here
                # A slipping pair exactly at v = 0 (a start at rest): no fall through zero
                # will be seen, so apply Eq. (14) now (as the fast engine).
                new, qd = switch(m, labels[i], self.s, self.y[:N_Q], self.y[N_Q:2 * N_Q],
                                 self.torque, self.speed, active, mode)
                self.y = self.y.copy()
                self.y[N_Q:2 * N_Q] = qd
                if new.stuck[j]:
                    self.mode = new
                    return 1, 0, ev0.mesh_force, ev0.mesh_force, 0.0
                mode.dirs[:] = new.dirs
                retest = True
        if retest:
            fun = self._rhs(active, mode, t0, s0)
            solver = solver_cls(fun, t0, self.y, tb, **kw)
            g_prev, ev0 = values(t0, self.y)
        n_steps = 0
        f_start = ev0.mesh_force  # the piece's start (after a boundary: the new pair set's)
        fmax, fmin = max(fmax, f_start), min(fmin, f_start)
        while True:
            msg = solver.step()
            if solver.status == "failed":
                raise ArithmeticError(f"{self.method} failed at t = {solver.t:.9g} s: {msg}")
            n_steps += 1
            ta, tc = solver.t_old, solver.t
            self._h = solver.step_size if solver.step_size else self._h
            sol = solver.dense_output()
            ts = np.linspace(ta, tc, self.n_samples + 2)[1:]
            hit = None
            t_prev = ta
            t_seen, f_seen = [ta], [f_start]
            for tk in ts:
                yk = sol(tk)
                gk, evk = values(tk, yk)
                if len(gk):
                    falls = np.flatnonzero((g_prev > 0.0) & (gk <= 0.0))
                    if falls.size:  # the force at tk is the old state's, past the switch
                        hit = (t_prev, tk, falls)
                        break
                t_seen.append(tk)
                f_seen.append(evk.mesh_force)
                g_prev, t_prev = gk, tk
            if hit is None:
                missed = self._missed(ta, g_prev, labels, values, sol, solver.y)
                if missed.size:
                    # a flank function below zero at the step's end with no fall seen: it
                    # was at zero or below at every sample (a positive sample before a value
                    # at or below zero is a fall), so it stood at zero at the step's start
                    # (at rest, flanks just touching, driven through zero by a load). Locate
                    # its fall in [ta, first sample] as one the scan saw, and redo the rest
                    # of the step from there; the samples are the wrong state's: drop them.
                    hit = (ta, ts[0], missed)
                    t_seen, f_seen = [ta], [f_start]

            def force(t, sol=sol):
                return self._mesh_force(t, sol(t), active, mode, t0, s0)
            if hit is not None:
                t_lo, tk, falls = hit
                # Refine the earliest of the falling functions.
                best_t, best_i = tk, int(falls[0])
                for i in falls:
                    def gi(t, i=i, sol=sol):
                        return values(t, sol(t))[0][i]
                    lo = t_lo if gi(t_lo) > 0.0 else _first_positive(gi, t_lo, tk)
                    te = t_lo if lo is None else _past_root(gi, lo, tk)
                    if te < best_t:
                        best_t, best_i = te, int(i)
                te = best_t
                ye = sol(te)
                if te > t_seen[-1]:
                    t_seen.append(te)
                    f_seen.append(force(te))
                fmax, fmin = self._step_extremes(force, t_seen, f_seen, fmax, fmin)
                fint += self._mesh_force_integral(sol, ta, te, active, mode, t0, s0)
                self._book(t0, te, mode)
                self.y = ye
                self.s = s0 + m.p.rb1 * self.speed * (te - t0)
                self.t = te
                qd = ye[N_Q:2 * N_Q]
                kind, j = labels[best_i]
                if kind == "pair" and mode.stuck[j]:
                    self._released = (j, te)
                self.mode, qd = switch(m, labels[best_i], self.s, ye[:N_Q], qd, self.torque,
                                       self.speed, active, mode)
                self.y = ye.copy()
                self.y[N_Q:2 * N_Q] = qd
                return 1, n_steps, fmax, fmin, fint
            self._guard(tc, g_prev, labels, evk, solver.y)
            fmax, fmin = self._step_extremes(force, t_seen, f_seen, fmax, fmin)
            f_start = f_seen[-1]
            fint += self._mesh_force_integral(sol, ta, tc, active, mode, t0, s0)
            if solver.status == "finished" or tc >= tb:
                self._book(t0, tb, mode)
                self.y = solver.y.copy()
                self.s = s0 + m.p.rb1 * self.speed * (tb - t0)
                self.t = tb
                return 0, n_steps, fmax, fmin, fint

    def _noise(self, y, off: int) -> float:
        """What rounding alone puts into the DTE (off 0) or its rate (off N_Q)."""
        return 64.0 * np.finfo(float).eps * float(np.abs(G) @ np.abs(y[off:off + N_Q]))

    def _start_flanks(self, g, labels, ev) -> int | None:
        """The flank functions at the start of a piece (as the fast engine's
        `events.start_flanks`): the index of one whose switch is due now (below zero beyond
        rounding, or at zero and falling), else None; one at zero and rising is set to
        `G_START` in g, so that a fall right after it counts."""
        tol, rtol = self._noise(self.y, 0), self._noise(self.y, N_Q)
        for i, (kind, _j) in enumerate(labels):
            if kind == "pair":
                continue
            if g[i] < -tol:
                return i
            if g[i] <= 0.0:
                # +DTE (drive flank in contact; back-flank gap while apart), else -DTE
                sign = 1.0 if (kind == "sep" and not self.mode.separated) or \
                    (kind == "back" and not self.mode.back) else -1.0
                r = sign * ev.ddelta
                if r > rtol:
                    g[i] = G_START
                elif r < -rtol:
                    return i
        return None

    def _switch_now(self, label, active, mode: Mode, ev0) -> tuple:
        """Apply a flank switch due at the start of a piece (`_integrate_segment`)."""
        m = self.model
        self.mode, qd = switch(m, label, self.s, self.y[:N_Q], self.y[N_Q:2 * N_Q],
                               self.torque, self.speed, active, mode)
        self.y = self.y.copy()
        self.y[N_Q:2 * N_Q] = qd
        return 1, 0, ev0.mesh_force, ev0.mesh_force, 0.0

    def _missed(self, ta: float, g, labels, values, sol, y) -> np.ndarray:
        """The flank functions below zero (beyond rounding) at the end of a step with no
        fall seen (g: their values there, y: the state there; as the fast engine's
        `events.mark_missed`), which `_integrate_segment` locates and redoes. Raises
        `RunFailure` when it cannot: one was below zero beyond rounding at the step's start
        ``ta`` already (the state was wrong before the step; ``sol``: its dense output)."""
        tol = self._noise(y, 0)
        missed = np.array([i for i, (kind, _j) in enumerate(labels)
                           if kind != "pair" and g[i] < -tol], dtype=int)
        if missed.size:
            y0 = sol(ta)
            g0, ev0 = values(ta, y0)
            if np.any(g0[missed] < -self._noise(y0, 0)):
                cs = 2 if self.mode.back else 1 if self.mode.separated else 0
                b0, b1 = self._dte_bound
                raise RunFailure(run_failure_message("missed", ta, cs, ev0.delta,
                                                     b0 + b1 * abs(self.torque)))
        return missed

    def _guard(self, t: float, g, labels, ev, y) -> None:
        """The check after every accepted step (as the fast engine's `events.flank_guard`):
        |DTE| within its bound (`Model.dte_bound`) at the step's end (time t, state y,
        evaluation ev); raises `RunFailure` otherwise. (A flank function below zero with no
        fall seen is located and redone before it: `_missed`.)"""
        cs = 2 if self.mode.back else 1 if self.mode.separated else 0
        b0, b1 = self._dte_bound
        bound = b0 + b1 * abs(self.torque)
        back = math.isfinite(self.model.backlash)
        if not ev.delta <= bound or (back and not ev.delta >= -self.model.backlash - bound):
            raise RunFailure(run_failure_message("unbounded", t, cs, ev.delta, bound))

    def _book(self, ta, tb, mode: Mode):
        if mode.back:  # on the back flank: contact, not contact loss
            self.t_back += tb - ta
        elif mode.separated:
            self.t_sep += tb - ta
        elif mode.stuck.any():
            self.t_stick += tb - ta

    # -- outputs -----------------------------------------------------------------------------
    def evaluate_now(self):
        """`equations.Eval` at the current time and state."""
        active, _, _, _, _ = self.model.contact(self.s, self._prev_active)
        return self._eval_at(self.t, self.y, active, self.mode, self.t, self.s), active

    def outputs(self) -> Outputs:
        m, p = self.model, self.model.p
        ev, active = self.evaluate_now()
        q, qd = self.y[:N_Q], self.y[N_Q:2 * N_Q]
        mesh = ev.mesh_force
        if self.mode.separated:
            state = CONTACT_BACK if self.mode.back else CONTACT_SEPARATED
        elif self.mode.stuck[active].any():
            state = CONTACT_STICK
        else:
            state = CONTACT_SLIP
        damp = ev.theta * p.cm * ev.ddelta
        reaction = p.rb1 * (mesh + damp) - float(ev.friction @ ev.s1m)
        i_near = int(np.argmin(np.abs(ev.xi - m.geom.xi_pitch))) if len(ev.xi) else 0
        return Outputs(
            time=self.t,
            dte=ev.delta,
            mesh_force=mesh,
            friction_force=float(ev.friction.sum()),
            contact_state=state,
            output_torque=-p.rb2 * (p.kr2 * (q[U2] - self.y[A]) + p.cr2 * (qd[U2] - self.y[AD])),
            input_torque_reaction=reaction,
            input_torque=self.torque - p.rb1 * (p.kr1 * q[U1] + p.cr1 * qd[U1]),
            gear1_speed=self.speed + qd[U1] / p.rb1,
            gear2_speed=self.speed * p.ratio - qd[U2] / p.rb2,
            sliding_velocity=float(ev.v[i_near]) if len(ev.v) else 0.0,
        )

    def energy(self) -> dict:
        """Stored energy and the integrated power terms so far (J)."""
        m = self.model
        ev, _ = self.evaluate_now()
        q, qd = self.y[:N_Q], self.y[N_Q:2 * N_Q]
        stored = 0.5 * qd @ m.M @ qd + 0.5 * q @ m.Kb @ q + 0.5 * ev.km * ev.compression**2 \
            + 0.5 * m.p.kr2 * ((q[U2] - self.y[A]) ** 2 - q[U2] ** 2)
        return {"stored": float(stored), "input": float(self.y[12]),
                "damping": float(self.y[13]), "friction": float(self.y[14]),
                "parametric": float(self.y[15])}
