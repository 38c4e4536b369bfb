"""Load FMU (pythonfmu slave): an inertia with viscous damping and a load torque.

``J dw/dt = torque - T_L(t) - c w`` with the driving ``torque`` held over each communication
step and ``T_L(t) = T_load`` before ``t_step`` and ``T_load + T_step`` from then on (a load
change for checking that power flows both ways). ``T_L`` is a constant torque against the
positive sense of rotation (a hoist, a conveyor on a slope), whatever the speed. Each step is
solved exactly, split at ``t_step`` when it falls inside, so the result does not depend on
how a master chops time (a ``t_step`` within 1e-9 s of a communication point counts as at it).

Connect ``GearPair.output_torque`` to ``torque`` and ``speed`` to ``GearPair.load_speed``.
``VARIABLES`` is the interface; ``build.py`` reads it to complete the modelDescription.
"""

from __future__ import annotations

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import Real

# name, causality, unit, display unit, min, max, start, description
VARIABLES: tuple[tuple, ...] = (
    ("torque", "input", "N.m", None, -1e7, 1e7, 0.0,
     "driving torque on the load shaft, held over each step (connect GearPair.output_torque)"),
    ("speed", "output", "rad/s", "rpm", None, None, None,
     "load speed at the end of the step (connect to GearPair.load_speed)"),
    ("resisting_torque", "output", "N.m", None, None, None, None,
     "T_L + c speed at the end of the step: the torque the load takes in steady state"),
    ("J", "parameter", "kg.m2", None, 1e-6, 1e7, 404.8,
     "load inertia plus everything turning rigidly with it (add the gear pair's J2: the "
     "GearPair FMU does not accelerate it with its speed input)"),
    ("c", "parameter", "N.m.s/rad", None, 0.0, 1e7, 50.0,
     "viscous damping coefficient"),
    ("T_load", "parameter", "N.m", None, -1e7, 1e7, 8000.0,
     "constant load torque against the positive sense of rotation"),
    ("T_step", "parameter", "N.m", None, -1e7, 1e7, 0.0,
     "change of the load torque at t_step"),
    ("t_step", "parameter", "s", None, 0.0, 1e9, 1e9,
     "time of the load torque change"),
    ("w_start", "parameter", "rad/s", "rpm", -2e4, 2e4, 0.0,
     "load speed at the start time"),
)


def relax(w: float, a: float, b: float, J: float, h: float) -> float:
    """Exact solution of ``J dw/dt = a - b w`` after ``h`` seconds.

    Parameters
    ----------
    w : rad/s, speed at the start
    a : N.m, constant torque
    b : N.m.s/rad, viscous coefficient (>= 0)
    J : kg.m2, inertia
    h : s, duration

    Returns
    -------
    float : rad/s, speed after ``h``
    """
    x = b * h / J
    phi = 1.0 - 0.5 * x if x < 1e-8 else -math.expm1(-x) / x  # (1 - e^-x) / x
    return w + (a - b * w) * h / J * phi


class Load(Fmi2Slave):
    """Load inertia with viscous damping and a (stepped) constant load torque."""

    author = "gearpair project"
    description = ("Load for the GearPair driveline example: J dw/dt = torque - T_L(t) - c w")
    version = "0.1.0"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=2.0, step_size=1e-4)

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for name, causality, _unit, _du, _lo, _hi, start, doc in VARIABLES:
            setattr(self, name, 0.0 if start is None else float(start))
            kw = dict(causality=getattr(Fmi2Causality, causality), description=doc,
                      variability=Fmi2Variability.fixed if causality == "parameter"
                      else Fmi2Variability.continuous)
            if causality == "parameter":
                kw["initial"] = Fmi2Initial.exact
            self.register_variable(Real(name, **kw))
        self._t0 = 0.0

    def _problem(self) -> str | None:
        """A message naming the first parameter or input out of range, or None."""
        for name, causality, unit, _du, lo, hi, _start, _doc in VARIABLES:
            if causality == "output":
                continue
            x = getattr(self, name)
            if not (isinstance(x, float) and math.isfinite(x) and lo <= x <= hi):
                return f"{name} = {x!r} is out of range [{lo:g}, {hi:g}] {unit}"
        return None

    def _eps(self) -> float:
        """s: a load change this close to a communication point counts as at that point,
        whichever way the master's time grid (``t += h`` or integer nanoseconds) rounds."""
        return 1e-9 * max(1.0, abs(self.t_step))

    def _changed(self, t: float) -> bool:
        return t >= self.t_step - self._eps()

    def _load_torque(self, t: float) -> float:
        return self.T_load + (self.T_step if self._changed(t) else 0.0)

    def _update(self, t: float) -> None:
        self.resisting_torque = self._load_torque(t) + self.c * self.speed

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._t0 = float(start_time)

    def exit_initialization_mode(self):
        self.speed = float(self.w_start)
        if self._problem() is None:
            self._update(self._t0)

    def do_step(self, current_time: float, step_size: float) -> bool:
        try:
            msg = self._problem()
            if msg is None and not step_size > 0.0:
                msg = f"communication step size {step_size!r} must be > 0"
            if msg is not None:
                self.log(f"step refused: {msg}", Fmi2Status.error)
                return False
            t, t_end, w = float(current_time), float(current_time) + float(step_size), self.speed
            if t + self._eps() < self.t_step < t_end - self._eps():  # inside: split there
                w = relax(w, self.torque - self._load_torque(t), self.c, self.J,
                          self.t_step - t)
                t = self.t_step
            self.speed = relax(w, self.torque - self._load_torque(t), self.c, self.J, t_end - t)
            self._update(t_end)
            return True
        except Exception as e:  # noqa: BLE001 - an exception would be fmi2Fatal
            self.log(f"step failed: {type(e).__name__}: {e}", Fmi2Status.error)
            return False
