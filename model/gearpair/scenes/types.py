"""The scene: what to simulate (gear data, effects, input schedules, solver settings, outputs)
as frozen objects, and `Scene.run`, which simulates it with the fast or reference engine or
through the FMU."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..effects import Effects
from ..inputs import Constant, Schedule
from ..params import GearParams, OperatingPoint
from ..results import UNITS, Trajectory, simulate
from .errors import SceneError
from .fmu import run_fmu

ENGINES = ("fast", "reference", "fmu")
OUTPUT_NAMES = tuple(n for n in UNITS if n != "time")
T_END_MAX = 3600.0  # s; longer runs belong in a sweep, not one scene
STEP_MIN, STEP_MAX = 1e-7, 1.0  # s, communication step and output interval


@dataclass(frozen=True)
class Inputs:
    """Operating inputs as functions of time: torque on gear 1 (N.m), speed of gear 1 (rad/s).

    The engine samples them at the start of each communication step and holds them over it
    (an FMI master's zero-order hold).
    """

    torque: Schedule = Constant(OperatingPoint().torque)
    speed: Schedule = Constant(OperatingPoint().speed)


@dataclass(frozen=True)
class Solver:
    """How to integrate.

    Attributes
    ----------
    engine : {"fast", "reference", "fmu"}
    rtol : relative tolerance of the integrator
    step : communication step (s): inputs are sampled and held over it; ``None`` means the
        output interval
    static_start : start from static equilibrium under the initial torque
    """

    engine: str = "fast"
    rtol: float = 1e-8
    step: float | None = None
    static_start: bool = True


@dataclass(frozen=True)
class OutputSpec:
    """What to record.

    Attributes
    ----------
    names : columns written to CSV (``time`` always comes first)
    interval : sampling interval of the trajectory (s), a whole multiple of the step
    t_from : start of the steady window for ratios and statistics (s); ``None``: t_end / 2
    """

    names: tuple[str, ...] = OUTPUT_NAMES
    interval: float = 1e-4
    t_from: float | None = None


@dataclass(frozen=True)
class Scene:
    """A validated scene: everything a run needs (SI).

    Attributes
    ----------
    name : scene name (file stem unless ``name`` is given)
    params, effects : gear data and the effects the run includes
    inputs, solver, outputs : see `Inputs`, `Solver`, `OutputSpec`
    t_end : simulated time (s), from 0
    description : free text
    path : the scene file, if it came from one
    """

    name: str
    params: GearParams = field(default_factory=GearParams)
    effects: Effects = field(default_factory=Effects)
    inputs: Inputs = field(default_factory=Inputs)
    solver: Solver = field(default_factory=Solver)
    outputs: OutputSpec = field(default_factory=OutputSpec)
    t_end: float = 0.2
    description: str = ""
    path: Path | None = None

    @property
    def step(self) -> float:
        """Communication step (s)."""
        return self.outputs.interval if self.solver.step is None else self.solver.step

    @property
    def every(self) -> int:
        """Communication steps per output sample."""
        return max(1, int(round(self.outputs.interval / self.step)))

    @property
    def t_from(self) -> float:
        """Start of the steady window (s)."""
        t = self.outputs.t_from
        return 0.5 * self.t_end if t is None or t >= self.t_end else t

    def with_t_end(self, t_end: float) -> Scene:
        """The same scene over ``[0, t_end]`` (e.g. a short check). A steady window that
        would start after the new end becomes its second half."""
        if not (math.isfinite(t_end) and 0.0 < t_end <= T_END_MAX):
            raise SceneError(f"t_end = {t_end!r} is out of range; allowed (0, {T_END_MAX:g}] s")
        out = self.outputs
        if out.t_from is not None and out.t_from >= t_end:
            out = replace(out, t_from=None)
        return replace(self, t_end=float(t_end), outputs=out)

    def run(self, engine: str | None = None, *, fmu_path: str | Path | None = None) -> Trajectory:
        """Simulate the scene and return the trajectory sampled at the output interval.

        Parameters
        ----------
        engine : "fast", "reference" or "fmu"; default the scene's ``[solver] engine``
        fmu_path : the FMU for ``engine="fmu"``; default ``$GEARPAIR_FMU`` or
            ``dist/GearPair.fmu`` of the current folder, rebuilt when stale
            (`gearpair.scenes.location.find_fmu`)
        """
        engine = self.solver.engine if engine is None else engine
        if engine not in ENGINES:
            raise SceneError(f"engine = {engine!r} is not allowed; choose one of "
                             + ", ".join(ENGINES))
        if self.t_end < self.step * (1 - 1e-9):
            raise SceneError(f"t_end = {self.t_end:g} s is shorter than one step "
                             f"({self.step:g} s)")
        if engine == "fmu":
            traj = run_fmu(self, fmu_path)
        else:
            traj = simulate(self.params, self.effects, t_end=self.t_end,
                            torque=self.inputs.torque, speed=self.inputs.speed, dt=self.step,
                            engine=engine, static=self.solver.static_start,
                            rtol=self.solver.rtol)
        out = traj.decimate(self.every)
        out.meta.update(scene=self.name, engine=engine, t_end=self.t_end)
        return out
