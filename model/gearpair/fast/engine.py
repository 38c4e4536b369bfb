"""`FastEngine`: the `Engine` contract over the compiled functions, and the set-up of the
records they take (`layout`)."""

from __future__ import annotations

import math

import numpy as np

from ..effects import Effects
from ..engine import (
    OUTPUT_NAMES,
    RECORDED_FIGURES,
    Engine,
    Outputs,
    RunFailure,
    StepSummary,
    check_inputs,
    grid_inputs,
    run_failure_message,
)
from ..equations import U2, Model
from ..params import GearParams, check_rtol
from ..stepblock import (
    N_X,
    STEP_DONE,
    X_FMU,
    X_LOAD,
    X_LOADON,
    X_REC,
    X_SPEED,
    X_TEND,
    X_TORQUE,
)
from .detlinalg import STATUS_TEXT
from .layout import (
    I_IX,
    I_MAXEV,
    I_NIX,
    J_NEVTOT,
    J_NPREV,
    J_RESUME,
    J_SEP,
    L_NSLOT,
    L_SCRATCH,
    N_IST,
    N_O,
    N_OUT,
    N_PW,
    N_Q,
    N_REC,
    N_SC,
    N_ST,
    N_Y,
    NZ,
    O_BFAIL,
    O_CFAIL,
    O_DFAIL,
    O_NREJ,
    O_STATUS,
    O_TFAIL,
    P_MAXSTEP,
    P_RATIO,
    P_RB2,
    P_SPACING,
    R_FSTG,
    S_COMP,
    S_KM,
    STATUS_EVENTS,
    STATUS_MISSED,
    STATUS_STEP,
    STATUS_UNBOUNDED,
    T_BACK,
    T_H,
    T_LAST0,
    T_LAST1,
    T_S,
    T_SEP,
    T_SPEED,
    T_STICK,
    T_T,
    T_TORQUE,
    Y_A,
    HybridState,
    Work,
)
from .loop import eval_entry, outputs_entry, reset_entry
from .native import compiled, handoff_table, set_grid, step_entry
from .setup import FastOptions, run_setup  # noqa: F401 - FastOptions re-exported
from .setupmath import row_sum
from .tableaux import RK_NK

_new = tuple.__new__


def work_buffers(n: int) -> Work:
    """The work buffers for ``n`` tracked pairs."""
    lti_keys = np.zeros((L_NSLOT + 1, 4))
    lti_keys[:L_NSLOT, 0] = -1.0  # empty slots
    return Work(
        active=np.zeros(n, dtype=np.int64), trial=np.zeros(n, dtype=np.int64),
        bound_offs=np.zeros(3), bound_k=np.zeros(3, dtype=np.int64),
        stages=np.zeros((RK_NK, N_Y)), dense=np.zeros((R_FSTG + 1, max(N_Y, n + 2, RK_NK))),
        ytmp=np.zeros(N_Y), ynew=np.zeros(N_Y), g=np.zeros(n + 2), gprev=np.zeros(n + 2),
        pair=np.zeros((N_PW, n)), scal=np.zeros(N_SC), solve=np.zeros((n, n + 2)),
        lti_mats=np.zeros((L_SCRATCH + 12, NZ, NZ)), lti_keys=lti_keys,
        lti_vecs=np.zeros((6, max(NZ, N_Y))), summary=np.zeros(N_OUT),
        outputs=np.zeros(N_O))


def state_buffer(n: int) -> tuple[np.ndarray, HybridState]:
    """One float buffer and the `HybridState` of views into it (a rollback snapshot is one
    copy; the integer parts are int64 views of float64 words)."""
    cut = np.cumsum([0, N_Y, N_ST, N_IST, n, n, n])
    buf = np.zeros(int(cut[-1]))
    part = [buf[cut[i]:cut[i + 1]] for i in range(6)]
    return buf, HybridState(y=part[0], clock=part[1], mode=part[2].view(np.int64),
                            dirs=part[3], stuck=part[4].view(np.int64),
                            prev_active=part[5].view(np.int64))


class FastEngine(Engine):
    """numba engine implementing the `Engine` contract with the reference's physics.

    Parameters
    ----------
    params, effects : the gear pair and the effects to include
    rtol : relative tolerance of the Runge-Kutta error control
    **options : the integrator options of `FastOptions` (``atol``, ``max_step``,
        ``n_samples``, ``sample_spacing``, ``t_tol``, ``max_events``, ``exact_lti``,
        ``method``)
    """

    def __init__(self, params: GearParams | None = None, effects: Effects | None = None,
                 rtol: float = 1e-8, **options) -> None:
        opts = FastOptions(**options)
        check_rtol(rtol)
        m = self.model = Model.build(params, effects)
        self.rtol = float(rtol)
        st = m.stiff
        # the records from the compiled set-up (`setup`): the same bits as the FMU's
        self._md = run_setup(m.p, m.effects, rtol=self.rtol, options=opts,
                             table=(st.xi, st.k, st.km_mean) if st.kind == "table" else None).md
        mp, mi = self._md.par, self._md.flag
        self.atol = self._md.atol
        self.max_step = float(mp[P_MAXSTEP])
        self.sample_spacing = float(mp[P_SPACING])
        self.integrated = mi[I_IX:I_IX + mi[I_NIX]].copy()  # what Runge-Kutta integrates
        self._held_q = np.setdiff1d(np.arange(2 * N_Q), self.integrated)  # q, q' at rest
        self.method = opts.method
        n = m.geom.n_pairs
        self._state, self._hs = state_buffer(n)
        self._wk = work_buffers(n)
        # the compiled entry points take plain tuples (typed faster per call than named)
        self._args = (tuple(self._md), tuple(self._wk), tuple(self._hs))
        # the compiled step (`native`): its hand-off table, the rollback copy of the state and
        # the step block (this engine's own, or a caller's: `bind_block`)
        self._saved = np.zeros_like(self._state)
        self._entry = step_entry
        self._step = None  # the compiled step as a Python callable, once loaded (`native_step`)
        self.bind_block(np.zeros(N_X))
        self._outputs: Outputs | None = None  # cache, valid until the state changes
        self._o_fresh = False  # wk.outputs holds the outputs of the current state
        self.reset()

    # -- contract ----------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return float(self._hs.clock[T_T])

    def reset(self, t0: float = 0.0, torque: float = 0.0, speed: float = 0.0,
              static: bool = True) -> None:
        check_inputs(torque, speed)
        # compiled (`start.reset_state`), as the FMU's C layer initializes an engine
        status = reset_entry(*self._args, (float(t0), float(torque), float(speed), bool(static)))
        if status != 0:
            raise np.linalg.LinAlgError(
                f"the static equilibrium under torque {torque!r} N.m has no solution "
                f"(stiffness matrix: {STATUS_TEXT[status]})")
        self._stale()

    @property
    def _last(self) -> tuple | None:
        """(start, end) of the last step (s), or None: kept in the state buffer, so the
        compiled step (`native`) and a rollback keep it too."""
        st = self._hs.clock
        return None if math.isnan(st[T_LAST0]) else (float(st[T_LAST0]), float(st[T_LAST1]))

    @_last.setter
    def _last(self, last) -> None:
        self._hs.clock[T_LAST0:T_LAST1 + 1] = (math.nan, math.nan) if last is None else last

    def get_state(self) -> dict:
        hs = self._hs
        st, mode = hs.clock, hs.mode
        npv = int(mode[J_NPREV])
        return {
            "t": float(st[T_T]), "s": float(st[T_S]), "y": hs.y.copy(),
            "torque": float(st[T_TORQUE]), "speed": float(st[T_SPEED]),
            "separated": bool(mode[J_SEP]), "back": bool(mode[J_SEP] == 2),
            "dirs": hs.dirs.copy(),
            "stuck": hs.stuck.astype(bool), "t_stick": float(st[T_STICK]),
            "t_sep": float(st[T_SEP]), "t_back": float(st[T_BACK]),
            "n_events_total": int(mode[J_NEVTOT]),
            "h": float(st[T_H]) if st[T_H] > 0 else None,
            "prev_active": None if npv < 0 else [int(j) for j in hs.prev_active[:npv]],
            "resume": bool(mode[J_RESUME]),  # inside a segment after an FMU's early return
            "last": self._last,
        }

    def set_state(self, state: dict) -> None:
        y = np.asarray(state["y"], dtype=float)
        moving = [int(i) for i in self._held_q if y[i] != 0.0]
        if moving:
            raise ValueError(
                f"state: y[{moving[0]}] = {y[moving[0]]!r}, but with these effects "
                f"components {[int(i) for i in self._held_q]} of y (x1, y1, x2, y2 at "
                "indices 0, 1, 3, 4 and their rates 6 + i) are not simulated and must be 0")
        hs = self._hs
        st, mode = hs.clock, hs.mode
        st[T_T], st[T_S] = float(state["t"]), float(state["s"])
        hs.y[:] = y
        st[T_TORQUE], st[T_SPEED] = float(state["torque"]), float(state["speed"])
        mode[J_SEP] = (2 if state.get("back") else 1) if state["separated"] else 0
        hs.dirs[:] = np.asarray(state["dirs"], dtype=float)
        hs.stuck[:] = np.asarray(state["stuck"], dtype=bool).astype(np.int64)
        st[T_STICK], st[T_SEP] = float(state["t_stick"]), float(state["t_sep"])
        st[T_BACK] = float(state.get("t_back", 0.0))
        mode[J_NEVTOT] = int(state["n_events_total"])
        h = state.get("h")
        st[T_H] = float(h) if h else 0.0
        prev = state.get("prev_active")
        if prev is None:
            mode[J_NPREV] = -1
        else:
            mode[J_NPREV] = len(prev)
            hs.prev_active[:len(prev)] = np.asarray(prev, dtype=np.int64)
        mode[J_RESUME] = int(bool(state.get("resume", False)))
        self._last = state.get("last")
        self._stale()

    def _stale(self) -> None:
        """The state changed: both output caches (`output_values`, `outputs`) are stale."""
        self._outputs = None
        self._o_fresh = False

    def snapshot(self) -> tuple:
        """A cheap copy of the whole state for a rollback within this process (`restore`);
        `get_state` is the portable, picklable form."""
        return self._state.copy(), self._last

    def restore(self, snap: tuple) -> None:
        """Return to a `snapshot` of this engine."""
        self._state[:], self._last = snap
        self._stale()

    def bind_block(self, block: np.ndarray) -> None:
        """Let the compiled step read its inputs from and write its step record into
        ``block`` (float64[`layout.N_X`], `layout.X_*`), which the caller keeps alive: the
        FMU slave holds its input and output variables there."""
        if block.shape != (N_X,):
            raise ValueError(f"a step block has {N_X} values, not {block.shape}")
        self._block = block
        self._table = handoff_table(self._md, self._wk, self._hs, block, self._state,
                                    self._saved)
        self._table_address = int(self._table.ctypes.data)

    @property
    def block(self) -> np.ndarray:
        """The step block (`bind_block`)."""
        return self._block

    def native_step(self) -> tuple:
        """(Python callable, C address, table address) of this engine's compiled step
        (`gearpair.fast.native`): ``call(table_address)`` or, from C, ``int64_t
        step(int64_t table_address)`` advances the engine as the step block says and returns
        a `layout.STEP_*` code. Valid while this engine lives."""
        if self._step is None:
            self._step, self._step_address = compiled(self._entry)
        return self._step, self._step_address, self._table_address

    def advance_values(self, t_end: float, torque: float, speed: float,
                       load_speed: float | None = None) -> StepSummary:
        """`advance` for a caller that has validated the inputs (each microsecond counts):
        no input check; the compiled step (`native_step`) leaves the step record in the
        step block, `output_values` then has the outputs."""
        t_start = self.time
        if not (t_end > t_start):
            raise ValueError(f"t_end = {t_end!r} must be after the current time {t_start!r}")
        x = self._block
        x[X_FMU] = 0.0
        x[X_TEND], x[X_TORQUE], x[X_SPEED] = t_end, torque, speed
        x[X_LOADON], x[X_LOAD] = (0.0, 0.0) if load_speed is None else (1.0, load_speed)
        self._stale()
        step, _, table = self.native_step()
        if step(table) != STEP_DONE:
            self._raise_failure()
        self._o_fresh = True  # the step left the outputs in wk.outputs
        stick, sep, fmax, nev, nst, back, fmean, fmin = x[X_REC + N_O:].tolist()
        # tuple.__new__: the record without the keyword handling of its constructor
        return _new(StepSummary, (t_start, float(t_end), stick, sep, fmax, int(nev), int(nst),
                                  back, fmean, fmin))

    def _raise_failure(self) -> None:
        out = self._wk.summary
        status = int(out[O_STATUS])
        if status == STATUS_EVENTS:
            raise RuntimeError(
                f"more than {int(self._md.flag[I_MAXEV])} contact switches in one step "
                f"(t = {out[O_TFAIL]:.9g} s): the run stalls (docs/limits.md, event-count rule)")
        if status == STATUS_STEP:
            raise ArithmeticError(
                f"Runge-Kutta step size underflow at t = {out[O_TFAIL]:.9g} s")
        if status in (STATUS_MISSED, STATUS_UNBOUNDED):
            raise RunFailure(run_failure_message(
                "missed" if status == STATUS_MISSED else "unbounded", out[O_TFAIL],
                int(out[O_CFAIL]), out[O_DFAIL], out[O_BFAIL]))

    def warm_up(self) -> None:
        """Load the compiled step, which `run` and `advance_values` share (from the on-disk
        cache; the first call in a process takes 0.1-1 s), unless it is loaded."""
        self.native_step()

    def run(self, grid, torque, speed, load_speed=None) -> dict:
        """`Engine.run` in one compiled call: the same records as `advance_values` +
        `outputs` per point, without the Python round trip (about 20 us) per point."""
        grid, T, W, L = grid_inputs(self.time, grid, torque, speed, load_speed)
        mp = self._md.par
        yad = np.zeros(len(grid) - 1) if L is None else \
            np.ascontiguousarray(-mp[P_RB2] * (L - W * mp[P_RATIO]))
        n = len(grid)
        rec = np.zeros((N_REC, n))  # one contiguous row per signal: returned without a copy
        self._stale()
        step, _, table = self.native_step()
        self._block[X_FMU] = 0.0
        set_grid(self._table, (grid, T, W, yad, rec))
        try:
            filled = step(table)  # a recorded run (`native.step`)
        finally:
            set_grid(self._table)
        if filled > 1:
            self._last = (float(grid[filled - 2]), float(grid[filled - 1]))
        if filled < n:
            self._raise_failure()
        data = {k: rec[m] for m, k in enumerate(OUTPUT_NAMES[1:])}  # time first in Outputs
        data["contact_state"] = data["contact_state"].astype(int)
        for m, k in enumerate(RECORDED_FIGURES):
            data[k] = rec[N_O + m]
        return data

    # -- outputs -----------------------------------------------------------------------------
    def _now(self) -> int:
        return int(eval_entry(*self._args))

    def output_values(self) -> np.ndarray:
        """The `Outputs` values after ``time``, in field order, as the engine's own array
        (read it before the next step; `outputs` is the dataclass)."""
        if not self._o_fresh:
            outputs_entry(*self._args)
            self._o_fresh = True
        return self._wk.outputs

    def outputs(self) -> Outputs:
        if self._outputs is None:
            o = self.output_values()
            self._outputs = Outputs(self.time, float(o[0]), float(o[1]),
                                    float(o[2]), int(o[3]), float(o[4]), float(o[5]),
                                    float(o[6]), float(o[7]), float(o[8]), float(o[9]))
        return self._outputs

    def energy(self) -> dict:
        """Stored energy and the integrated power terms so far (J), as the reference."""
        m = self.model
        self._now()
        sc, y = self._wk.scal, self._hs.y
        q, qd = y[:N_Q], y[N_Q:2 * N_Q]
        # M and Kb are diagonal; summed in a fixed order (a BLAS dot product's order
        # depends on its kernel)
        stored = 0.5 * row_sum(np.diag(m.M) * qd * qd) + 0.5 * row_sum(np.diag(m.Kb) * q * q) \
            + 0.5 * sc[S_KM] * sc[S_COMP] * sc[S_COMP] \
            + 0.5 * m.p.kr2 * ((y[U2] - y[Y_A]) * (y[U2] - y[Y_A]) - y[U2] * y[U2])
        return {"stored": float(stored), "input": float(y[12]), "damping": float(y[13]),
                "friction": float(y[14]), "parametric": float(y[15])}

    @property
    def rejected_steps(self) -> int:
        """Runge-Kutta step attempts the error test rejected in the last `advance` (work that
        `StepSummary.n_steps` does not count)."""
        return int(self._wk.summary[O_NREJ])

    @property
    def stick_time(self) -> float:
        """Time spent with a pair stuck since reset (s)."""
        return float(self._hs.clock[T_STICK])

    @property
    def separation_time(self) -> float:
        """Time spent with no flank in contact since reset (s)."""
        return float(self._hs.clock[T_SEP])

    @property
    def back_time(self) -> float:
        """Time spent on the back flank since reset (s)."""
        return float(self._hs.clock[T_BACK])
