"""Simulation loop and results: trajectories in SI with time first, ratios of Eqs. (26)-(27).

`simulate` is a loop over `Engine.advance` on the output grid, with the inputs sampled at the
start of each interval and held over it — exactly what an FMI 2.0 co-simulation master does,
so the FMU and the core see the same inputs.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from .effects import Effects
from .engine import Engine, Outputs
from .params import RPM, GearParams, OperatingPoint

Input = float | Callable[[float], float]

# Units of the recorded columns, for CSV headers and conversions.
UNITS = {
    "time": "s", "dte": "m", "mesh_force": "N", "friction_force": "N", "contact_state": "1",
    "output_torque": "N.m", "input_torque_reaction": "N.m", "gear1_speed": "rad/s",
    "gear2_speed": "rad/s", "sliding_velocity": "m/s", "stick_fraction": "1",
    "separation_fraction": "1", "mesh_force_max": "N", "n_events": "1", "torque": "N.m",
    "speed": "rad/s",
}
_CONVERT = {("m", "um"): 1e6, ("N", "kN"): 1e-3, ("rad/s", "rpm"): 1 / RPM, ("m", "mm"): 1e3}


@dataclass
class Trajectory:
    """Recorded outputs (SI), one row per output instant, time first.

    ``data`` maps a column name (see `UNITS`) to an array. The step figures
    (``stick_fraction``, ``separation_fraction``, ``mesh_force_max``, ``n_events``) at row i
    describe the interval ending at ``time[i]``; row 0 is the initial state.
    """

    data: dict[str, np.ndarray]

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

    def ratios(self, t_from: float = 0.0) -> dict[str, float]:
        """Stick ratio r_k = t_k/t_t and contact-loss ratio r_l = t_l/t_t over the window
        after ``t_from`` (Eqs. (26)-(27)), from the located switching instants."""
        w = self.window(t_from)
        dt = np.diff(self.time, prepend=self.time[0])[w]
        tt = dt.sum()
        if tt <= 0:
            raise ValueError("the steady window is empty: t_from is past the end")
        return {
            "stick_ratio": float((self.data["stick_fraction"][w] * dt).sum() / tt),
            "contact_loss_ratio": float((self.data["separation_fraction"][w] * dt).sum() / tt),
        }

    def summary(self, t_from: float = 0.0) -> dict:
        """Ratios and mesh force min/mean/max (N) over the steady window."""
        w = self.window(t_from)
        f = self.data["mesh_force"][w]
        fmax = self.data["mesh_force_max"][w]
        out = self.ratios(t_from)
        out["mesh_force_n"] = {"min": float(f.min()), "mean": float(f.mean()),
                               "max": float(max(f.max(), fmax.max()))}
        out["window_s"] = [float(t_from), float(self.time[-1])]
        return out

    def to_csv(self, path: str | Path) -> None:
        """Write all columns with a ``name [unit]`` header."""
        names = list(self.data)
        with Path(path).open("w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow([f"{n} [{UNITS.get(n, '')}]" for n in names])
            cols = [self.data[n] for n in names]
            for i in range(len(self.time)):
                wr.writerow([f"{c[i]:.10g}" for c in cols])


def _as_fn(x: Input) -> Callable[[float], float]:
    if callable(x):
        return x
    v = float(x)
    return lambda t: v


def simulate(params: GearParams | None = None, effects: Effects | None = None,
             t_end: float = 0.2, torque: Input | None = None, speed: Input | None = None,
             dt: float = 1e-4, engine: str | Engine = "reference", t0: float = 0.0,
             static: bool = True, **engine_options) -> Trajectory:
    """Run one gear pair from ``t0`` to ``t_end`` and record every ``dt`` (s).

    Parameters
    ----------
    torque, speed : N.m and rad/s, constants or functions of time; sampled at the start of
        each output interval and held over it (as an FMI master does). Defaults: the
        `OperatingPoint` (3900 N.m, 100 r/min).
    engine : engine name for `gearpair.make_engine`, or an engine instance
    static : start from static equilibrium under the initial torque
    """
    from . import make_engine

    op = OperatingPoint()
    fT = _as_fn(op.torque if torque is None else torque)
    fW = _as_fn(op.speed if speed is None else speed)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt = {dt!r} must be a positive number of seconds")
    if not (t_end > t0):
        raise ValueError(f"t_end = {t_end!r} must be after t0 = {t0!r}")
    eng = engine if isinstance(engine, Engine) else make_engine(params, effects, engine,
                                                                **engine_options)
    n = int(round((t_end - t0) / dt))
    grid = t0 + dt * np.arange(n + 1)
    grid[-1] = t_end
    eng.reset(grid[0], fT(grid[0]), fW(grid[0]), static=static)
    names = [f.name for f in fields(Outputs)]
    cols = {k: np.zeros(n + 1) for k in names}
    extra = {k: np.zeros(n + 1) for k in ("stick_fraction", "separation_fraction",
                                          "mesh_force_max", "n_events", "torque", "speed")}

    def record(i, out: Outputs, summ=None, T=0.0, W=0.0):
        for k in names:
            cols[k][i] = getattr(out, k)
        extra["torque"][i], extra["speed"][i] = T, W
        if summ is not None:
            extra["stick_fraction"][i] = summ.stick_fraction
            extra["separation_fraction"][i] = summ.separation_fraction
            extra["mesh_force_max"][i] = summ.mesh_force_max
            extra["n_events"][i] = summ.n_events
        else:
            extra["mesh_force_max"][i] = out.mesh_force

    record(0, eng.outputs(), None, fT(grid[0]), fW(grid[0]))
    for i in range(1, n + 1):
        T, W = fT(grid[i - 1]), fW(grid[i - 1])
        summ = eng.advance(grid[i], T, W)
        record(i, eng.outputs(), summ, T, W)
    data = {"time": grid, **{k: v for k, v in cols.items() if k != "time"}, **extra}
    return Trajectory(data)
