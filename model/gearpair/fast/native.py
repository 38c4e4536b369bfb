"""The engine's step as one compiled function a C caller can call: ``step(handle) -> code``.

A *hand-off table* (an int64 array, `handoff_table`) holds the address and shape of every
array of an engine's records, of its state buffer, of a rollback copy of it and of a step
block (`layout.X_*`: the end of the step, the inputs, the step record). The compiled step
(`step_entry`; `step_early_entry` where a step may return early) rebuilds the
records from the table and advances the engine in place: no Python object is touched, so the
FMU's C layer calls it through its C address (`step_address`) without the interpreter, and
Python calls the same compiled code through numba's dispatcher (`FastEngine.advance_values`,
the FMU slave's ``do_step``). The arrays belong to the engine and the block to its caller;
both keep them referenced for as long as the table is used.

What a step does (`step`): with ``X_FMU`` set, the checks of an FMU's doStep (the
communication point within 1e-9 relative of the engine's time, inputs in range: else
`STEP_REFUSED` with nothing changed), a rollback copy of the state, `loop.advance` to
``X_TEND`` with the inputs held, the outputs and the step figures into the step record, and
on an engine failure or a non-finite value the state of the step start again
(`STEP_FAILED`, `STEP_NONFINITE`; the record keeps the last good step's values). Without
``X_FMU`` it advances as `FastEngine.advance_values` always did: no checks, no rollback.
``X_FMU`` = 2 is an FMU's doStep that may return early (FMI 3): the advance ends at the first
change of the contact state strictly inside the step (`loop.segment`), the engine's time
says where, and the record and figures are those of the step up to there.
"""

from __future__ import annotations

import math

import numpy as np
from numba import types

from ..engine import CONTACT_BACK, CONTACT_SEPARATED, CONTACT_STICK
from ..jitcache import jit_entry, jit_hot
from ..stepblock import (
    STEP_DONE,
    STEP_FAILED,
    STEP_NONFINITE,
    STEP_RECORD,
    STEP_REFUSED,
    X_BAD,
    X_FMU,
    X_H,
    X_LOAD,
    X_LOADON,
    X_REC,
    X_SPEED,
    X_TCHK,
    X_TEND,
    X_TORQUE,
)
from .layout import (
    L_NSLOT,
    O_FINT,
    O_FMAX,
    O_FMIN,
    O_NEV,
    O_NSTEPS,
    O_STATUS,
    P_RATIO,
    P_RB2,
    STATUS_OK,
    T_BACK,
    T_LAST0,
    T_LAST1,
    T_SEP,
    T_STICK,
    T_T,
    Y_AD,
    HybridState,
    ModelData,
    Work,
)
from .loop import advance, outputs_now, record_first, record_row, reset_settle
from .start import reset_state
from .views import array_at as _array_at

N_FIG = len(STEP_RECORD) - 10  # figures after the N_O outputs
# The hand-off table: 4 words (address, shape) per array, in this order; the kind of each
# (f: float64, i: int64; the number: dimensions) is what the compiled step reads it as.
_KINDS = {"md": "f1 i1 f1 f1 f1 f1",
          "wk": "i1 i1 f1 i1 f2 f2 f1 f1 f1 f1 f2 f1 f2 f3 f2 f2 f1 f1",
          "hs": "f1 f1 i1 f1 i1 i1",
          "own": "f1 f1 f1",  # the step block, the state buffer, its rollback copy
          # a recorded run (`FastEngine.run`, `set_grid`): the grid's times, the torque,
          # speed and load-shaft end rate of each interval and the records; empty for a step
          "grid": "f1 f1 f1 f1 f2"}
KINDS = tuple(k for part in _KINDS.values() for k in part.split())
N_TABLE = 4 * len(KINDS)
N_KINDS = len(KINDS)
K_GRID = N_KINDS - len(_KINDS["grid"].split())  # the first array of a recorded run


def handoff_table(md: ModelData, wk: Work, hs: HybridState, block: np.ndarray,
                  state: np.ndarray, saved: np.ndarray) -> np.ndarray:
    """The hand-off table of an engine's records and the caller's step ``block``.

    Raises ValueError unless every array is C-contiguous with the dtype and dimensions the
    compiled step reads (`KINDS`). The table holds addresses only: the caller keeps every
    array alive while the table is in use.
    """
    arrays = (*md, *wk, *hs, block, state, saved)
    if len(arrays) != K_GRID:
        raise ValueError(f"a hand-off table takes {K_GRID} arrays, not {len(arrays)}")
    table = np.zeros(N_TABLE, dtype=np.int64)  # no recorded run: its arrays empty
    for k, a in enumerate(arrays):
        _put(table, k, a, writeable=True)
    return table


def _put(table: np.ndarray, k: int, a: np.ndarray, writeable: bool) -> None:
    """Array ``k`` of a hand-off table: its address and dimensions, once checked against
    `KINDS` (the compiled step reads it as that kind, and writes where ``writeable``)."""
    kind = KINDS[k]
    dtype = np.float64 if kind[0] == "f" else np.int64
    if a.dtype != dtype or a.ndim != int(kind[1]) or not a.flags.c_contiguous or \
            (writeable and not a.flags.writeable):
        raise ValueError(f"hand-off array {k} is {a.dtype}[{a.ndim}d], not {kind}")
    table[4 * k] = a.ctypes.data
    table[4 * k + 1:4 * k + 1 + a.ndim] = a.shape


def set_grid(table: np.ndarray, arrays=None) -> None:
    """Put a recorded run's arrays (grid, torque, speed, load-shaft end rate: float64[n]
    and float64[n - 1], C-contiguous; the records: float64[N_REC, n]) into a hand-off
    table, or take them out (None: the table steps once again). The caller keeps them
    alive while they are in the table."""
    table[4 * K_GRID:] = 0
    if arrays is None:
        return
    for k, a in enumerate(arrays, K_GRID):
        _put(table, k, a, writeable=k == N_KINDS - 1)  # only the records are written


@jit_hot
def records(tab):
    """(ModelData, Work, HybridState, (step block, state buffer, its rollback copy)) from a
    hand-off table (`KINDS`' order: 4 words per array, its address and dimensions)."""
    def f1(k):
        return _array_at(tab[4 * k], (tab[4 * k + 1],), 0.0)

    def i1(k):
        return _array_at(tab[4 * k], (tab[4 * k + 1],), 0)

    def f2(k):
        return _array_at(tab[4 * k], (tab[4 * k + 1], tab[4 * k + 2]), 0.0)

    md = ModelData(f1(0), i1(1), f1(2), f1(3), f1(4), f1(5))
    wk = Work(i1(6), i1(7), f1(8), i1(9), f2(10), f2(11), f1(12), f1(13), f1(14), f1(15),
              f2(16), f1(17), f2(18),
              _array_at(tab[76], (tab[77], tab[78], tab[79]), 0.0),  # 19: lti_mats
              f2(20), f2(21), f1(22), f1(23))
    hs = HybridState(f1(24), f1(25), i1(26), f1(27), i1(28), i1(29))
    return md, wk, hs, (f1(30), f1(31), f1(32)), (f1(33), f1(34), f1(35), f1(36), f2(37))


@jit_hot
def refused(x, st):
    """Whether the FMU's doStep must not begin: the communication point is not the engine's
    time (within 1e-9 relative, as the slave's check), the step does not end after it, or
    an input is out of range (`gearpair.engine.check_inputs`). The slave's own checks then
    say which."""
    t, h = x[X_TCHK], x[X_H]
    if not (abs(t - st[T_T]) <= 1e-9 * max(1.0, abs(t), h) and x[X_TEND] > st[T_T]):
        return True
    if not (abs(x[X_TORQUE]) <= 1e6 and abs(x[X_SPEED]) <= 2e4):
        return True
    return x[X_LOADON] != 0.0 and not abs(x[X_LOAD]) <= 2e4


@jit_hot
def figures(wk, st, start):
    """The step figures in `StepSummary`'s order after the times, as `STEP_RECORD` has
    them; ``start``: time, stick, separation and back-flank times at the step's start."""
    summ, f = wk.summary, wk.outputs[1]
    h = st[T_T] - start[0]
    # max(peak, force at the end) and min(...) as Python's max and min pick them
    return ((st[T_STICK] - start[1]) / h, (st[T_SEP] - start[2]) / h,
            f if f > summ[O_FMAX] else summ[O_FMAX], summ[O_NEV], summ[O_NSTEPS],
            (st[T_BACK] - start[3]) / h, summ[O_FINT] / h,
            f if f < summ[O_FMIN] else summ[O_FMIN])


@jit_hot
def first_not_finite(o, fig):
    """The record slot of the first value that is not finite, or -1."""
    n_o = o.shape[0]
    for m in range(n_o + N_FIG):
        v = o[m] if m < n_o else fig[m - n_o]
        if not math.isfinite(v):
            return m
    return -1


@jit_hot
def step(tab, early_ok):
    """One step of the engine of the hand-off table ``tab`` (module docstring); returns a
    `STEP_*` code. ``early_ok``: None compiles a step that never returns early (numba
    prunes the early return for its type), True one that does where ``X_FMU`` is 2.

    With a recorded run in the table (``grid`` not empty: `FastEngine.run`), it advances to
    every point of the grid instead, with the inputs of each interval held, records the
    outputs and the interval's figures in ``rec`` (`loop.record_row`) and returns the
    number of columns filled: fewer than the grid's points when the step into the next one
    failed (``wk.summary`` says why). The same `advance` call serves both, so the engine is
    compiled once."""
    md, wk, hs, (x, state, saved), (grid, torque, speed, yad, rec) = records(tab)
    st, mp, summ = hs.clock, md.par, wk.summary
    rows = grid.shape[0]
    fmu = x[X_FMU] != 0.0
    if fmu:
        if refused(x, st):
            return STEP_REFUSED
        for m in range(state.shape[0]):
            saved[m] = state[m]
    if rows > 0:
        record_first(md, wk, hs, rec)
    i = 1
    while True:
        if rows > 0:
            if i >= rows:
                return rows
            t_end, tq, w = grid[i], torque[i - 1], speed[i - 1]
            hs.y[Y_AD] = yad[i - 1]
        else:
            t_end, tq, w = x[X_TEND], x[X_TORQUE], x[X_SPEED]
            hs.y[Y_AD] = 0.0 if x[X_LOADON] == 0.0 else \
                -mp[P_RB2] * (x[X_LOAD] - w * mp[P_RATIO])
        start = (st[T_T], st[T_STICK], st[T_SEP], st[T_BACK])
        if early_ok is None:
            advance(md, wk, hs, t_end, tq, w, None)
        else:
            early = (start[0], t_end) if x[X_FMU] == 2.0 else (np.nan, np.nan)
            advance(md, wk, hs, t_end, tq, w, early)
        if rows == 0:
            break
        if summ[O_STATUS] != STATUS_OK:
            return i
        record_row(md, wk, hs, rec, i, start)
        i += 1
    code = STEP_FAILED
    if wk.summary[O_STATUS] == STATUS_OK:
        outputs_now(md, wk, hs)
        fig = figures(wk, st, start)
        bad = first_not_finite(wk.outputs, fig) if fmu else -1
        x[X_BAD] = bad
        if bad < 0:
            code = STEP_DONE
            st[T_LAST0] = start[0]
            st[T_LAST1] = st[T_T]  # t_end, or where an early return stopped
            o, n_o = wk.outputs, wk.outputs.shape[0]
            for m in range(n_o):
                x[X_REC + m] = o[m]
            for m in range(N_FIG):
                x[X_REC + n_o + m] = fig[m]
        else:
            code = STEP_NONFINITE
    if code != STEP_DONE and fmu:
        for m in range(state.shape[0]):
            state[m] = saved[m]
    return code


@jit_hot
def initialize(tab):
    """Reset the engine of the hand-off table ``tab`` to the static equilibrium at time
    X_TCHK under the inputs X_TORQUE, X_SPEED (`start.reset_state`, then the slip
    directions; no exact propagator cached), and put the outputs there into the step record
    with the figures of an empty step (`gearpair.engine.StepSummary.at_instant`), as an FMU
    shows them before its first step. Returns STEP_DONE, STEP_REFUSED (an input out of
    range: nothing changed), STEP_FAILED (no static equilibrium) or STEP_NONFINITE."""
    md, wk, hs, (x, _, _), _ = records(tab)
    if not (abs(x[X_TORQUE]) <= 1e6 and abs(x[X_SPEED]) <= 2e4 and math.isfinite(x[X_TCHK])):
        return STEP_REFUSED
    keys = wk.lti_keys  # no propagator cached (`engine.work_buffers`)
    for slot in range(keys.shape[0]):
        for c in range(keys.shape[1]):
            keys[slot, c] = -1.0 if slot < L_NSLOT and c == 0 else 0.0
    if reset_state(md, wk, hs, (x[X_TCHK], x[X_TORQUE], x[X_SPEED], True)) != 0:
        return STEP_FAILED
    reset_settle(md, wk, hs)
    outputs_now(md, wk, hs)
    o, f = wk.outputs, wk.outputs[1]
    cs = o[3]
    fig = (1.0 if cs == CONTACT_STICK else 0.0, 1.0 if cs == CONTACT_SEPARATED else 0.0, f,
           0.0, 0.0, 1.0 if cs == CONTACT_BACK else 0.0, f, f)
    bad = first_not_finite(o, fig)
    x[X_BAD] = bad
    if bad >= 0:
        return STEP_NONFINITE
    n_o = o.shape[0]
    for m in range(n_o):
        x[X_REC + m] = o[m]
    for m in range(N_FIG):
        x[X_REC + n_o + m] = fig[m]
    return STEP_DONE


# -- entry points: called from Python through numba's dispatcher, from C at their address --
@jit_entry
def step_entry(table_address):
    """`step` of the engine of the hand-off table at ``table_address``."""
    return step(_array_at(table_address, (N_TABLE,), 0), None)


@jit_entry
def step_early_entry(table_address):
    """`step` that may return early (``X_FMU`` 2: FMI 3's early return), compiled only
    where it is called (the FMU's object, `gearpair.aot`): the engine's own steps never
    return early."""
    return step(_array_at(table_address, (N_TABLE,), 0), True)


@jit_entry
def init_entry(table_address):
    """`initialize` the engine of the hand-off table at ``table_address``."""
    return initialize(_array_at(table_address, (N_TABLE,), 0))


def compiled(dispatcher) -> tuple:
    """(Python callable, C address) of a step entry point: the compiled function called
    without numba's per-call typing, and its C wrapper ``int64_t step(int64_t table)``.
    Loads (or compiles) it on first use, without running it."""
    sig = (types.int64,)
    cres = dispatcher.overloads.get(sig)
    if cres is None:
        dispatcher.compile(sig)
        cres = dispatcher.overloads[sig]
    address = cres.library.get_pointer_to_function(cres.fndesc.llvm_cfunc_wrapper_name)
    return cres.entry_point, int(address)
