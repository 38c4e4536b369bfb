"""Input schedules: the operating inputs (torque, speed) as functions of time, SI values.

Every schedule is a frozen callable ``f(t)`` (``t`` in s) with a vectorized ``sample(t)``
that returns exactly the pointwise values for a whole grid in one call (what the compiled
recorder of `gearpair.results.simulate` is fed). Scenes (`gearpair.scenes`) build them from
TOML; `simulate` takes them, or any plain callable, or a number (a `Constant`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

_T_TOL = 1e-12  # s: a sample this close to a step's `at` counts as at it (grid round-off)


@dataclass(frozen=True)
class Constant:
    """The same value at all times (an input schedule; `sample` feeds a whole grid to the
    compiled recorder in one call)."""

    value: float

    def __call__(self, t: float) -> float:
        return self.value

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Values at the times ``t`` (one vectorized call for a whole grid)."""
        return np.full(np.shape(t), float(self.value))


@dataclass(frozen=True)
class Ramp:
    """``start`` until ``t0``, linear to ``end`` at ``t1`` (s), ``end`` after."""

    start: float
    end: float
    t0: float
    t1: float

    def __call__(self, t: float) -> float:
        if t <= self.t0:
            return self.start
        if t >= self.t1:
            return self.end
        return self.start + (self.end - self.start) * (t - self.t0) / (self.t1 - self.t0)

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Values at the times ``t`` (one vectorized call for a whole grid)."""
        t = np.asarray(t, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):  # t1 == t0: the middle is unused
            mid = self.start + (self.end - self.start) * (t - self.t0) / (self.t1 - self.t0)
        return np.where(t <= self.t0, float(self.start), np.where(t >= self.t1,
                                                                  float(self.end), mid))


@dataclass(frozen=True)
class Step:
    """``before`` for t < ``at`` (s), ``after`` from ``at`` on."""

    before: float
    after: float
    at: float

    def __call__(self, t: float) -> float:
        return self.after if t >= self.at - _T_TOL else self.before

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Values at the times ``t`` (one vectorized call for a whole grid)."""
        return np.where(np.asarray(t, dtype=float) >= self.at - _T_TOL, float(self.after),
                        float(self.before))


@dataclass(frozen=True)
class Series:
    """A time series (from CSV): linear between rows, first/last value held outside.

    Attributes
    ----------
    time : s, strictly increasing
    values : SI values at ``time``
    source : where it came from (``file:column``), for messages
    """

    time: tuple[float, ...]
    values: tuple[float, ...]
    source: str = ""
    _t: np.ndarray = field(init=False, repr=False, compare=False)
    _v: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # Arrays once: the loop samples the schedule at every communication point.
        object.__setattr__(self, "_t", np.asarray(self.time, dtype=float))
        object.__setattr__(self, "_v", np.asarray(self.values, dtype=float))

    def __call__(self, t: float) -> float:
        return float(np.interp(t, self._t, self._v))

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Values at the times ``t`` (one vectorized call for a whole grid)."""
        return np.interp(np.asarray(t, dtype=float), self._t, self._v)


@dataclass(frozen=True)
class Function:
    """A plain function of time ``fn(t)`` as a schedule: `sample` calls it at each time."""

    fn: Callable[[float], float]

    def __call__(self, t: float) -> float:
        return self.fn(t)

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Values at the times ``t``, one call of ``fn`` each."""
        return np.fromiter((self.fn(x) for x in t), float, len(t))


Schedule = Constant | Ramp | Step | Series | Function


def as_schedule(x: float | Callable[[float], float]) -> Schedule:
    """A schedule as is, a number as a `Constant`, any other callable as a `Function`."""
    if isinstance(x, (Constant, Ramp, Step, Series, Function)):
        return x
    return Function(x) if callable(x) else Constant(float(x))
