"""Simulation loop and results: trajectories in SI with time first, ratios of Eqs. (26)-(27).

`simulate` is one `Engine.run` over the output grid (a loop over `Engine.advance`, or the
engine's own compiled recorder), with the inputs sampled at the start of each interval and
held over it — exactly what an FMI 2.0 co-simulation master does,
so the FMU and the core see the same inputs.
"""

from __future__ import annotations

import csv
import math
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .effects import Effects
from .engine import CONTACT_BACK, OUTPUT_NAMES, Engine
from .engine import UNITS as ENGINE_UNITS
from .inputs import Function, as_schedule
from .params import RPM, GearParams, OperatingPoint

Input = float | Callable[[float], float]

# Units of the recorded columns (the engine's records and the inputs), for CSV headers and
# conversions, in the order files list them (the figures added later come last).
_UNITS = {**ENGINE_UNITS, "torque": "N.m", "speed": "rad/s", "load_speed": "rad/s"}
UNITS = {k: _UNITS[k] for k in (*OUTPUT_NAMES, "stick_fraction", "separation_fraction",
                                "mesh_force_max", "n_events", "torque", "speed", "load_speed",
                                "back_fraction", "mesh_force_mean", "mesh_force_min")}
_CONVERT = {("m", "um"): 1e6, ("N", "kN"): 1e-3, ("rad/s", "rpm"): 1 / RPM, ("m", "mm"): 1e3}
# Figures that describe the interval ending at their row (not an instant): merged, not sampled,
# when rows are dropped.
_FRACTIONS = ("stick_fraction", "separation_fraction", "back_fraction", "mesh_force_mean")


@dataclass
class Trajectory:
    """Recorded outputs (SI), one row per output instant, time first.

    ``data`` maps a column name (see `UNITS`) to an array. The step figures
    (``stick_fraction``, ``separation_fraction``, ``back_fraction``, ``mesh_force_mean``,
    ``mesh_force_min``, ``mesh_force_max``, ``n_events``; `StepSummary`) at row i describe the
    interval ending at ``time[i]``; row 0 is the initial state. ``torque`` and ``speed`` at
    row i are the inputs held over that interval. ``meta`` holds how the run was made
    (``engine``, ``wall_time_s`` of the run itself, ``startup_s`` of building the engine and
    loading its compiled code), not results.
    """

    data: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[name]

    @property
    def time(self) -> np.ndarray:
        return self.data["time"]

    def get(self, name: str, unit: str | None = None) -> np.ndarray:
        """Column ``name`` converted to ``unit`` (e.g. dte in um, mesh_force in kN)."""
        x = self.data[name]
        base = UNITS.get(name, "")
        if unit is None or unit == base:
            return x
        try:
            return x * _CONVERT[(base, unit)]
        except KeyError:
            raise ValueError(f"cannot convert {name} from {base} to {unit}") from None

    def window(self, t_from: float) -> np.ndarray:
        """Mask of the intervals ending after ``t_from`` (a steady window)."""
        return self.time > t_from + 1e-12

    def _time_mean(self, name: str, t_from: float) -> float:
        """Time mean of a per-interval figure over the window after ``t_from``."""
        w = self.window(t_from)
        dt = np.diff(self.time, prepend=self.time[0])[w]
        tt = dt.sum()
        if tt <= 0:
            raise ValueError("the steady window is empty: t_from is past the end")
        return float((self.data[name][w] * dt).sum() / tt)

    def ratios(self, t_from: float = 0.0) -> dict[str, float]:
        """Stick ratio r_k = t_k/t_t and contact-loss ratio r_l = t_l/t_t over the window
        after ``t_from`` (Eqs. (26)-(27)), from the located switching instants, and the
        back-flank contact ratio (time on the back flank with `Effects.backlash`: contact
        under a negative torque, not contact loss)."""
        out = {"stick_ratio": self._time_mean("stick_fraction", t_from),
               "contact_loss_ratio": self._time_mean("separation_fraction", t_from)}
        if "back_fraction" in self.data:
            out["back_contact_ratio"] = self._time_mean("back_fraction", t_from)
        elif "contact_state" in self.data:  # an FMU without the output: its samples
            w = self.window(t_from)
            out["back_contact_ratio_sampled"] = float(np.mean(self.data["contact_state"][w]
                                                              == CONTACT_BACK))
        return out

    def summary(self, t_from: float = 0.0) -> dict:
        """Ratios, the mesh force over the steady window and the DTE at the output instants.

        ``mesh_force_n``: ``mean`` is the time mean from the engine's integral over every
        integrator step (not a mean of samples, which at a fixed output interval locks to
        phases of the mesh period), ``min`` and ``max`` the least and greatest force of the
        trajectory (`StepSummary.mesh_force_min`/``max``: turning points located inside
        every integrator step, so they do not depend on the output interval). A record
        without a step figure (an FMU lacking that output) gives the statistic of the output
        samples instead, named ``mean_sampled``, ``min_sampled``, ``max_sampled`` (and
        `ratios` ``back_contact_ratio_sampled``). ``dte_m_sampled``: statistics of the DTE
        at the output instants only.
        """
        w = self.window(t_from)
        f = self.data["mesh_force"][w]
        out = self.ratios(t_from)
        force = {}
        if "mesh_force_min" in self.data:
            force["min"] = min(float(f.min()), float(self.data["mesh_force_min"][w].min()))
        else:
            force["min_sampled"] = float(f.min())
        if "mesh_force_mean" in self.data:
            force["mean"] = self._time_mean("mesh_force_mean", t_from)
        else:
            force["mean_sampled"] = float(f.mean())
        if "mesh_force_max" in self.data:
            force["max"] = max(float(f.max()), float(self.data["mesh_force_max"][w].max()))
        else:
            force["max_sampled"] = float(f.max())
        out["mesh_force_n"] = force
        d = self.data["dte"][w]
        out["dte_m_sampled"] = {"min": float(d.min()), "mean": float(d.mean()),
                                "max": float(d.max()), "std": float(d.std()),
                                "peak_to_peak": float(d.max() - d.min())}
        out["window_s"] = [float(t_from), float(self.time[-1])]
        return out

    def decimate(self, every: int) -> Trajectory:
        """Keep row 0, every ``every``-th row and the last row.

        Instantaneous columns are sampled; the step figures are merged over the dropped
        intervals (fractions and the mean force weighted by interval length,
        ``mesh_force_max`` the peak, ``mesh_force_min`` the least, ``n_events`` the sum), so
        `ratios` and the force figures do not depend on ``every``.
        """
        every = int(every)
        n = len(self.time) - 1
        if every <= 1 or n <= 1:
            return self
        keep = np.arange(0, n + 1, every)
        if keep[-1] != n:
            keep = np.append(keep, n)
        data = {k: v[keep].copy() for k, v in self.data.items()}
        # Intervals 1..n (interval i ends at row i); kept row keep[j] closes the group of
        # intervals keep[j-1]+1 .. keep[j], i.e. indices keep[j-1] .. keep[j]-1 below.
        starts = keep[:-1]
        dt = np.diff(self.time)
        span = np.add.reduceat(dt, starts)
        for k in _FRACTIONS:
            if k in self.data:
                data[k][1:] = np.add.reduceat(self.data[k][1:] * dt, starts) / span
        if "mesh_force_max" in self.data:
            data["mesh_force_max"][1:] = np.maximum.reduceat(self.data["mesh_force_max"][1:],
                                                             starts)
        if "mesh_force_min" in self.data:
            data["mesh_force_min"][1:] = np.minimum.reduceat(self.data["mesh_force_min"][1:],
                                                             starts)
        if "n_events" in self.data:
            data["n_events"][1:] = np.add.reduceat(self.data["n_events"][1:], starts)
        return Trajectory(data, dict(self.meta))

    def to_csv(self, path: str | Path, names: Sequence[str] | None = None) -> None:
        """Write ``time`` and the columns ``names`` (default: all), SI values with 10
        significant digits.

        The header holds the plain names (units in `UNITS` and docs/scenes.md), so the file
        goes unchanged into ``fmpy simulate --input-file`` (the columns ``torque``, ``speed``
        and ``load_speed`` are the FMU's inputs) and into a scene's ``[inputs.csv]``.
        """
        names = ["time"] + [n for n in (self.data if names is None else names) if n != "time"]
        unknown = [n for n in names if n not in self.data]
        if unknown:
            raise ValueError(f"no column {', '.join(unknown)}; recorded: {', '.join(self.data)}")
        with Path(path).open("w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow(names)
            cols = [self.data[n] for n in names]
            for i in range(len(self.time)):
                wr.writerow([f"{c[i]:.10g}" for c in cols])

    def plot(self, path: str | Path, title: str | None = None) -> None:
        """Draw DTE, mesh force, friction force and contact state against time into ``path``
        (format from its suffix, e.g. ``.png``, ``.pdf``). Needs matplotlib (extra ``plot``).
        """
        try:  # matplotlib stays optional: the core never needs it
            from matplotlib.figure import Figure
        except ImportError:
            raise ImportError("plotting needs matplotlib: pip install 'gearpair[plot]'") from None
        t = self.time
        # Figure without pyplot: no GUI backend is selected and no global state is touched.
        fig = Figure(figsize=(8.0, 8.0), layout="constrained")
        ax = fig.subplots(4, 1, sharex=True)
        ax[0].plot(t, self.get("dte", "um"), lw=0.8)
        ax[0].set_ylabel("DTE (um)")
        if "mesh_force_max" in self.data:  # behind the samples: it only adds the peaks
            ax[1].plot(t[1:], self.get("mesh_force_max", "kN")[1:], lw=0.6, color="0.6",
                       label="peak in interval")
        ax[1].plot(t, self.get("mesh_force", "kN"), lw=0.8, label="at sample")
        ax[1].legend(loc="upper right", fontsize="small")
        ax[1].set_ylabel("mesh force (kN)")
        ax[2].plot(t, self.get("friction_force", "kN"), lw=0.8)
        ax[2].set_ylabel("friction force (kN)")
        state = self.data["contact_state"]
        labels = ["separated", "slip", "stick"] + (["back flank"] if np.any(state == 3) else [])
        ax[3].step(t, state, where="post", lw=0.8)
        ax[3].set_yticks(range(len(labels)), labels)
        ax[3].set_ylim(-0.3, len(labels) - 0.7)
        ax[3].set_xlabel("time (s)")
        for a in ax:
            a.grid(True, lw=0.3)
        if title:
            fig.suptitle(title)
        fig.savefig(Path(path), dpi=120)


def _ratio(eng: Engine, params: GearParams | None) -> float:
    """z1/z2 of the engine's gears: the load shaft's far end turns at ``z1/z2 speed`` (the
    nominal rotation of gear 2) in every run of `simulate`, which drives no load shaft."""
    model = getattr(eng, "model", None)
    return float(model.p.ratio if model is not None else (params or GearParams()).ratio)


def _check_load(eng: Engine, params: GearParams | None, fT, grid: np.ndarray) -> None:
    """Warn (`GearDataWarning`, before the run) when the largest torque of the run loads the
    teeth beyond what steel gears carry (`gearpair.geometry.load_implausibility`). A plain
    function is sampled at up to 1001 points of the grid; a schedule (``sample``) at all."""
    from .geometry import warn_implausible_load

    model = getattr(eng, "model", None)
    p = model.p if model is not None else (params or GearParams())
    if isinstance(fT, Function):
        pick = grid if len(grid) <= 1001 else grid[np.linspace(0, len(grid) - 1, 1001,
                                                               dtype=np.int64)]
        torques = fT.sample(pick)
    else:
        torques = fT.sample(grid)
    # the caller of `simulate` (or of `Scene.run`) is where the torque came from
    warn_implausible_load(p, float(np.max(np.abs(torques))), stacklevel=3)


def simulate(params: GearParams | None = None, effects: Effects | None = None,
             t_end: float = 0.2, torque: Input | None = None, speed: Input | None = None,
             dt: float = 1e-4, engine: str | Engine = "fast", t0: float = 0.0,
             static: bool = True, **engine_options) -> Trajectory:
    """Run one gear pair from ``t0`` to ``t_end`` and record every ``dt`` (s).

    Parameters
    ----------
    torque, speed : N.m and rad/s, constants or functions of time; sampled at the start of
        each output interval and held over it (as an FMI master does). Defaults: the
        `OperatingPoint` (3900 N.m, 100 r/min).
    engine : engine name for `gearpair.make_engine` (``"fast"``, the default, or
        ``"reference"``, the scipy yardstick), or an engine instance
    static : start from static equilibrium under the initial torque

    The trajectory's ``meta`` has ``startup_s`` (building the engine and loading its
    compiled code, once per process) apart from ``wall_time_s`` (the run itself).
    """
    from . import make_engine

    op = OperatingPoint()
    fT = as_schedule(op.torque if torque is None else torque)
    fW = as_schedule(op.speed if speed is None else speed)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt = {dt!r} must be a positive number of seconds")
    if not (t_end > t0):
        raise ValueError(f"t_end = {t_end!r} must be after t0 = {t0!r}")
    wall0 = _time.perf_counter()
    eng = engine if isinstance(engine, Engine) else make_engine(params, effects, engine,
                                                                **engine_options)
    n = int(round((t_end - t0) / dt))
    grid = t0 + dt * np.arange(n + 1)
    grid[-1] = t_end
    _check_load(eng, params, fT, grid)
    eng.warm_up()  # compiled code loaded now counts as start-up, not run time
    startup = _time.perf_counter() - wall0
    wall0 = _time.perf_counter()
    eng.reset(grid[0], fT(grid[0]), fW(grid[0]), static=static)
    T, W = fT.sample(grid[:-1]), fW.sample(grid[:-1])
    data = {"time": grid, **eng.run(grid, T, W)}
    data["torque"] = np.r_[fT(grid[0]), T]
    data["speed"] = np.r_[fW(grid[0]), W]
    data["load_speed"] = data["speed"] * _ratio(eng, params)
    name = engine if isinstance(engine, str) else type(engine).__name__
    return Trajectory(data, {"engine": name, "wall_time_s": _time.perf_counter() - wall0,
                             "startup_s": startup})
