"""The engine contract shared by every integrator, the FMU, the CLI and the sweeps.

An engine owns one gear pair's continuous state (q, q', mesh travel) and discrete state
(which pairs stick, the slip direction of each pair, separated or not). It is driven by
``advance(t_end, torque, speed)``, which integrates to ``t_end`` exactly with the inputs held
over the step (zero-order hold, as an FMI 2.0 co-simulation master gives them), locating every
state switch inside the step, and returns the step record `StepSummary`; ``run`` does the same
over a grid and records it. Front doors (FMU, CLI, harness) never care which engine runs: they
call these methods of `Engine`, never ask which ones an engine has.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from .params import SPEED_MAX, TORQUE_MAX

CONTACT_SEPARATED = 0
CONTACT_SLIP = 1
CONTACT_STICK = 2
CONTACT_BACK = 3  # back flanks in contact (Effects.backlash)


class RunFailure(ValueError):
    """A run stopped because its result cannot be trusted (issue 38): a contact event was
    missed (the contact state and the geometry disagree after a step), or the DTE left its
    physical bound (`Model.dte_bound`). Both engines raise it with `run_failure_message`;
    the FMU answers the step with fmi2Error and this message, a sweep stores the point as
    ``invalid`` with it."""


# What a flank (separation) function exactly at zero at the start of a piece is taken as, in
# both engines: the least normal double, so that a fall below zero right after it counts
# (an event function must fall from > 0 to <= 0; the event that ended the last piece can
# leave the DTE at exactly 0.0, and a re-contact microseconds later went unnoticed)
G_START = 2.2250738585072014e-308

# the engines' contact codes (0 drive flanks, 1 apart, 2 back flanks) in words
FLANK_STATE = ("on the drive flanks", "apart (no flank in contact)", "on the back flanks")


def run_failure_message(kind: str, t: float, cs: int, dte: float, bound: float) -> str:
    """The message of a `RunFailure`: ``kind`` "missed" or "unbounded", at time t (s), in
    contact code ``cs`` (0, 1, 2), with the DTE (m) and the compression bound (m) there."""
    where = (f"at t = {t:.9g} s the teeth are {FLANK_STATE[cs]} with DTE = {dte:.6g} m")
    if kind == "missed":
        return (f"missed contact event: {where}, which the geometry contradicts (a flank in "
                "tension or overlapping flanks apart); the run is stopped rather than "
                "continued with teeth passing through each other (docs/limits.md)")
    return (f"unbounded response: {where}, a flank compressed by more than its physical "
            f"bound {bound:.4g} m (0.1 module plus 20 static deflections under the torque): "
            "the teeth would pass through each other; often a "
            "parametric instability of the model at this operating point (docs/limits.md)")


@dataclass(frozen=True)
class Outputs:
    """Instantaneous outputs at the engine's current time (SI).

    Attributes
    ----------
    time : s
    dte : m, mesh deflection delta = g . q along the line of action (Eq. (3))
    mesh_force : N, elastic mesh force km Theta(delta) delta (Eq. (16)); on the back flank
        km (delta + b) < 0
    friction_force : N, total tangential tooth force (sliding or static), sum over pairs
    contact_state : 0 separated, 1 slip, 2 stick (any pair stuck), 3 back flank in contact
    output_torque : N.m, torque delivered to the gear 2 shaft, -rb2 (kr2 (u2 - a) + cr2 (u2' - a'))
        with a the load-shaft end (0 unless a load speed drives it)
    input_torque_reaction : N.m, torque the mesh exerts back on gear 1 about its axis
    input_torque : N.m, torque the input side delivers into gear 1: the torque input plus the
        input shaft's -rb1 (kr1 u1 + cr1 u1'); what a motor driving the pair must supply
    gear1_speed, gear2_speed : rad/s, absolute shaft speeds (nominal + vibration)
    sliding_velocity : m/s, relative sliding velocity of the pair nearest the pitch point
    """

    time: float
    dte: float
    mesh_force: float
    friction_force: float
    contact_state: int
    output_torque: float
    input_torque_reaction: float
    input_torque: float
    gear1_speed: float
    gear2_speed: float
    sliding_velocity: float


class StepSummary(NamedTuple):
    """The step record: figures over the last ``advance`` call that stay meaningful at
    coarse steps (units in `UNITS`). A named tuple, so the FMU's doStep gets it for the
    price of a tuple; read it by name.

    Attributes
    ----------
    t_start, t_end : s
    stick_fraction, separation_fraction : fraction (0..1) of the step spent in stick / with
        no flank in contact (contact loss), from the located switching instants (exact, not
        sampled)
    mesh_force_max : N, greatest elastic mesh force in the step: the extreme of the
        trajectory, not of samples (the values at every integrator step's end, switch and
        segment boundary, and each step's turning points located from the step's own end
        values and time derivatives, refined on its continuous extension), so it does not
        depend on the output interval beyond the integration tolerance
    n_events : number of state switches located in the step
    n_steps : number of internal integrator steps
    back_fraction : fraction (0..1) of the step on the back flank (contact under a negative
        torque with `Effects.backlash`, `contact_state` 3), exact as the others
    mesh_force_mean : N, time mean of the elastic mesh force over the step: its integral
        over every integrator step (the Runge-Kutta quadrature of the stage values, Gauss
        points on the continuous extension up to a switch; the exact propagator's own
        stretches by the slope-corrected trapezoid), divided by the step length
    mesh_force_min : N, least elastic mesh force in the step, located as ``mesh_force_max``
    """

    t_start: float
    t_end: float
    stick_fraction: float
    separation_fraction: float
    mesh_force_max: float
    n_events: int
    n_steps: int
    back_fraction: float = 0.0
    mesh_force_mean: float = math.nan
    mesh_force_min: float = math.nan

    @classmethod
    def at_instant(cls, out: Outputs) -> StepSummary:
        """The figures of an empty step at ``out.time``, as the FMU shows them before its
        first step: each fraction 1 or 0 by the contact state there, the mesh force for its
        mean and extremes."""
        cs, f = int(out.contact_state), out.mesh_force
        return cls(out.time, out.time, float(cs == CONTACT_STICK),
                   float(cs == CONTACT_SEPARATED), f, 0, 0, float(cs == CONTACT_BACK), f, f)


OUTPUT_NAMES = tuple(f.name for f in fields(Outputs))
# What `Engine.run` records at every grid point besides the outputs: the step figures of the
# interval ending there (the compiled recorder, `fast.loop.record_row`, writes them in this order)
RECORDED_FIGURES = ("stick_fraction", "separation_fraction", "mesh_force_max", "n_events",
                    "back_fraction", "mesh_force_mean", "mesh_force_min")
# Units of both records' fields (SI; "1" dimensionless)
UNITS = {
    "time": "s", "dte": "m", "mesh_force": "N", "friction_force": "N", "contact_state": "1",
    "output_torque": "N.m", "input_torque_reaction": "N.m", "input_torque": "N.m",
    "gear1_speed": "rad/s", "gear2_speed": "rad/s", "sliding_velocity": "m/s",
    "t_start": "s", "t_end": "s", "stick_fraction": "1", "separation_fraction": "1",
    "mesh_force_max": "N", "n_events": "1", "n_steps": "1", "back_fraction": "1",
    "mesh_force_mean": "N", "mesh_force_min": "N",
}


class Engine(ABC):
    """The contract every engine implements (`gearpair.reference.ReferenceEngine`,
    `gearpair.fast.FastEngine`), and what it gets for free.

    An engine implements `reset`, `advance_values`, `outputs`, `get_state`, `set_state` and
    `time`; `advance` (with the input check), `run` (a loop over the grid), `output_values`,
    `snapshot`/`restore` and `warm_up` have plain defaults here that an engine may replace
    by faster ones with the same results (the fast engine records a whole grid in one
    compiled call).
    """

    #: The compiled step the FMU's C layer calls without Python, for an engine that has one
    #: (`FastEngine.native_step`: a method returning the callable and its addresses);
    #: ``None`` for an engine that steps in Python only.
    native_step = None

    def bind_block(self, block) -> None:
        """Step with the caller's step block (the FMU slave's); an engine without a
        compiled step has no block and ignores it."""
        return None

    @abstractmethod
    def reset(self, t0: float = 0.0, torque: float = 0.0, speed: float = 0.0,
              static: bool = True) -> None:
        """Start at ``t0``; with ``static`` the deflections start at static equilibrium
        under ``torque`` (so a run has no start-up transient from zero)."""

    def advance(self, t_end: float, torque: float, speed: float,
                load_speed: float | None = None) -> StepSummary:
        """Integrate to exactly ``t_end`` with torque (N.m) and speed (rad/s) held.

        ``load_speed`` (rad/s, in gear 2's sense of rotation) drives the far end of the load
        shaft kr2/cr2 when the pair sits between two inertias (a driveline); ``None`` keeps
        the paper's load shaft, anchored to the nominal rotation Omega1 z1/z2. Raises
        ``ValueError`` naming an input out of range (`check_inputs`)."""
        check_inputs(torque, speed, load_speed)
        return self.advance_values(t_end, torque, speed, load_speed)

    @abstractmethod
    def advance_values(self, t_end: float, torque: float, speed: float,
                       load_speed: float | None = None) -> StepSummary:
        """`advance` for a caller that has validated the inputs (`check_inputs`; the FMU's
        doStep, where each microsecond counts)."""

    def run(self, grid, torque, speed, load_speed=None) -> dict[str, np.ndarray]:
        """Step through ``grid`` (s, from the current time) and record at every point.

        Parameters
        ----------
        grid : increasing times (s); ``grid[0]`` is the current time
        torque, speed, load_speed : N.m, rad/s, rad/s per interval (``len(grid) - 1``
            values or one for all, held from ``grid[i]`` to ``grid[i + 1]``); ``load_speed``
            None as in `advance`

        Returns
        -------
        dict of arrays over ``grid``: the `Outputs` fields after ``time`` and the step
        figures `RECORDED_FIGURES` of the interval ending there (row 0, the start: no
        interval, so fractions and events 0, the mesh force for its mean and extremes).
        This loop calls `advance_values` per interval.
        """
        grid, T, W, L = grid_inputs(self.time, grid, torque, speed, load_speed)
        n = len(grid)
        rec = {k: np.zeros(n) for k in (*OUTPUT_NAMES[1:], *RECORDED_FIGURES)}
        rec["contact_state"] = np.zeros(n, dtype=int)

        def put(i: int, summ: StepSummary) -> None:
            out = self.outputs()
            for k in OUTPUT_NAMES[1:]:
                rec[k][i] = getattr(out, k)
            for k in RECORDED_FIGURES:
                rec[k][i] = getattr(summ, k)

        t, f = self.time, self.outputs().mesh_force
        put(0, StepSummary(t, t, 0.0, 0.0, f, 0, 0, 0.0, f, f))
        for i in range(1, n):
            put(i, self.advance_values(float(grid[i]), float(T[i - 1]), float(W[i - 1]),
                                       None if L is None else float(L[i - 1])))
        return rec

    @abstractmethod
    def outputs(self) -> Outputs:
        """Outputs at the current time."""

    def output_values(self) -> np.ndarray:
        """The `Outputs` values after ``time``, in field order, as an array (the FMU copies
        them every step; `outputs` is the record)."""
        out = self.outputs()
        return np.array([getattr(out, k) for k in OUTPUT_NAMES[1:]], dtype=float)

    @abstractmethod
    def get_state(self) -> dict:
        """Everything the next step depends on, as plain Python/numpy values (picklable)."""

    @abstractmethod
    def set_state(self, state: dict) -> None:
        """Restore a state from `get_state` (of an engine built with the same data)."""

    def snapshot(self):
        """A copy of the whole state for a rollback within this process (`restore`); here
        `get_state`, which an engine may replace by a cheaper copy."""
        return self.get_state()

    def restore(self, snap) -> None:
        """Return to a `snapshot` of this engine."""
        self.set_state(snap)

    def warm_up(self) -> None:  # noqa: B027 - a hook: most engines compile nothing
        """Load whatever the engine compiles before a run, so that the run's time does not
        include it (once per process); the state is left as it was. Here: nothing."""

    @property
    @abstractmethod
    def time(self) -> float:
        """Current time (s)."""


def check_inputs(torque: float, speed: float, load_speed: float | None = None) -> None:
    """Raise ``ValueError`` naming the input unless torque and speed are finite and in range
    (`params.TORQUE_MAX`, `params.SPEED_MAX`)."""
    if type(torque) is float and type(speed) is float and abs(torque) <= TORQUE_MAX and \
            abs(speed) <= SPEED_MAX and (load_speed is None or (type(load_speed) is float
                                                                and abs(load_speed) <= SPEED_MAX)):
        return  # the usual case (the FMU's, every step) in one test; nan fails it
    rows = [("torque", torque, TORQUE_MAX, "N.m"), ("speed", speed, SPEED_MAX, "rad/s")]
    if load_speed is not None:
        rows.append(("load_speed", load_speed, SPEED_MAX, "rad/s"))
    for name, v, lim, unit in rows:
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number, got {v!r}") from None
        if not math.isfinite(x) or abs(x) > lim:
            raise ValueError(f"{name} = {v!r} is out of range; allowed [-{lim:g}, {lim:g}] {unit}")


def grid_inputs(now: float, grid, torque, speed, load_speed=None) -> tuple:
    """Validated (grid, torque, speed, load_speed) arrays for `Engine.run` from the engine's
    time ``now``: the grid starts there and increases strictly, the inputs (one value per
    interval, or one for all; ``load_speed`` may be None) are finite and in range; raises
    ``ValueError`` as `check_inputs` does for the first bad interval."""
    grid = np.ascontiguousarray(grid, dtype=float)
    n = len(grid)
    if n < 1 or abs(grid[0] - now) > 1e-12 * max(1.0, abs(now)):
        raise ValueError(f"grid must start at the current time {now!r}")
    if n > 1 and not np.all(np.diff(grid) > 0):
        raise ValueError("grid must increase strictly")
    T = np.ascontiguousarray(np.broadcast_to(np.asarray(torque, float), (n - 1,)))
    W = np.ascontiguousarray(np.broadcast_to(np.asarray(speed, float), (n - 1,)))
    L = None if load_speed is None else np.broadcast_to(np.asarray(load_speed, float), (n - 1,))
    ok = np.isfinite(T) & np.isfinite(W) & (np.abs(T) <= TORQUE_MAX) & (np.abs(W) <= SPEED_MAX)
    if L is not None:
        ok &= np.isfinite(L) & (np.abs(L) <= SPEED_MAX)
    if not np.all(ok):  # the same message as advance, for the first bad interval
        i = int(np.argmin(ok))
        check_inputs(T[i], W[i], None if L is None else L[i])
    return grid, T, W, L


def as_array(x) -> np.ndarray:
    return np.asarray(x, dtype=float)
