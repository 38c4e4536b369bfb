"""The engine contract shared by every integrator, the FMU, the CLI and the sweeps.

An engine owns one gear pair's continuous state (q, q', mesh travel) and discrete state
(which pairs stick, the slip direction of each pair, separated or not). It is driven by
``advance(t_end, torque, speed)``, which integrates to ``t_end`` exactly with the inputs held
over the step (zero-order hold, as an FMI 2.0 co-simulation master gives them), locating every
state switch inside the step. Front doors (FMU, CLI, harness) never care which engine runs.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

CONTACT_SEPARATED = 0
CONTACT_SLIP = 1
CONTACT_STICK = 2
CONTACT_BACK = 3  # back flanks in contact (Effects.backlash)


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


@dataclass(frozen=True)
class StepSummary:
    """Figures over the last ``advance`` call that stay meaningful at coarse steps.

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


class Engine(ABC):
    """Abstract engine. Concrete engines: `gearpair.reference.ReferenceEngine`."""

    @abstractmethod
    def reset(self, t0: float = 0.0, torque: float = 0.0, speed: float = 0.0,
              static: bool = True) -> None:
        """Start at ``t0``; with ``static`` the deflections start at static equilibrium
        under ``torque`` (so a run has no start-up transient from zero)."""

    @abstractmethod
    def advance(self, t_end: float, torque: float, speed: float,
                load_speed: float | None = None) -> StepSummary:
        """Integrate to exactly ``t_end`` with torque (N.m) and speed (rad/s) held.

        ``load_speed`` (rad/s, in gear 2's sense of rotation) drives the far end of the load
        shaft kr2/cr2 when the pair sits between two inertias (a driveline); ``None`` keeps
        the paper's load shaft, anchored to the nominal rotation Omega1 z1/z2."""

    @abstractmethod
    def outputs(self) -> Outputs:
        """Outputs at the current time."""

    @abstractmethod
    def get_state(self) -> dict:
        """Everything the next step depends on, as plain Python/numpy values (picklable)."""

    @abstractmethod
    def set_state(self, state: dict) -> None:
        """Restore a state from `get_state` (of an engine built with the same data)."""

    @property
    @abstractmethod
    def time(self) -> float:
        """Current time (s)."""


def check_inputs(torque: float, speed: float, load_speed: float | None = None) -> None:
    """Raise ``ValueError`` naming the input unless torque and speed are finite and in range."""
    if type(torque) is float and type(speed) is float and abs(torque) <= 1e6 and \
            abs(speed) <= 2e4 and (load_speed is None or (type(load_speed) is float
                                                          and abs(load_speed) <= 2e4)):
        return  # the usual case (the FMU's, every step) in one test; nan fails it
    rows = [("torque", torque, 1e6, "N.m"), ("speed", speed, 2e4, "rad/s")]
    if load_speed is not None:
        rows.append(("load_speed", load_speed, 2e4, "rad/s"))
    for name, v, lim, unit in rows:
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number, got {v!r}") from None
        if not math.isfinite(x) or abs(x) > lim:
            raise ValueError(f"{name} = {v!r} is out of range; allowed [-{lim:g}, {lim:g}] {unit}")


def as_array(x) -> np.ndarray:
    return np.asarray(x, dtype=float)
