"""Motor FMU (pythonfmu slave): a rotor inertia driven by a torque-speed characteristic.

The characteristic is an induction-motor-like droop with a torque limit (a drive's current
limit)::

    T_m(w) = clip(T_stall * (1 - w / w_noload), -T_max, T_max)

and the rotor obeys ``J dw/dt = T_m(w) - load_torque`` with ``load_torque`` held over each
communication step. Each piece of the characteristic is linear in ``w``, so a step is solved
exactly (exponential in the droop, a ramp at the limit, the switch between them located in
closed form): the result does not depend on how a master chops time.

Connect ``speed`` to ``GearPair.speed`` and ``GearPair.input_torque`` to ``load_torque``.
``VARIABLES`` is the interface; ``build.py`` reads it to complete the modelDescription.
"""

from __future__ import annotations

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import Real

RPM = 2.0 * math.pi / 60.0  # rad/s per r/min

# name, causality, unit, display unit, min, max, start, description
VARIABLES: tuple[tuple, ...] = (
    ("load_torque", "input", "N.m", None, -1e7, 1e7, 0.0,
     "torque the driven machine takes from the rotor, held over each step "
     "(connect GearPair.input_torque)"),
    ("speed", "output", "rad/s", "rpm", None, None, None,
     "rotor speed at the end of the step (connect to GearPair.speed)"),
    ("torque", "output", "N.m", None, None, None, None,
     "motor torque T_m(speed) of the characteristic at the end of the step"),
    ("J", "parameter", "kg.m2", None, 1e-6, 1e6, 2.139,
     "rotor inertia plus everything turning rigidly with it (add the gear pair's J1: the "
     "GearPair FMU does not accelerate it with its speed input)"),
    ("T_stall", "parameter", "N.m", None, 1e-3, 1e8, 60000.0,
     "torque of the droop line at standstill (the droop is T_stall / w_noload)"),
    ("w_noload", "parameter", "rad/s", "rpm", 1e-3, 2e4, 400.0 * RPM,
     "no-load speed, where the droop line crosses zero torque"),
    ("T_max", "parameter", "N.m", None, 1e-3, 1e8, 6000.0,
     "torque limit of the drive in either direction"),
    ("w_start", "parameter", "rad/s", "rpm", -2e4, 2e4, 0.0,
     "rotor speed at the start time"),
)


def characteristic(w: float, T_stall: float, w_noload: float, T_max: float) -> float:
    """Motor torque of the characteristic.

    Parameters
    ----------
    w : rad/s, rotor speed
    T_stall : N.m, torque of the droop line at standstill
    w_noload : rad/s, speed where the droop line crosses zero torque
    T_max : N.m, torque limit in either direction

    Returns
    -------
    float : N.m, ``clip(T_stall (1 - w / w_noload), -T_max, T_max)``
    """
    return min(T_max, max(-T_max, T_stall * (1.0 - w / w_noload)))


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


def advance(w: float, load: float, h: float, J: float, T_stall: float, w_noload: float,
            T_max: float) -> float:
    """Rotor speed after ``h`` seconds under a held load torque, solved exactly.

    Parameters
    ----------
    w : rad/s, rotor speed at the start
    load : N.m, load torque held over the step
    h : s, step
    J, T_stall, w_noload, T_max : kg.m2, N.m, rad/s, N.m: the FMU's parameters

    Returns
    -------
    float : rad/s, rotor speed after ``h``

    Notes
    -----
    The speed moves monotonically (a first-order autonomous equation), so it crosses at most
    the two knees of the characteristic, ``w_lo`` (limit +T_max below) and ``w_hi`` (limit
    -T_max above); each crossing time is found in closed form.
    """
    k = T_stall / w_noload  # droop, N.m.s/rad
    w_lo = w_noload * (1.0 - T_max / T_stall)
    w_hi = w_noload * (1.0 + T_max / T_stall)
    left = h
    for _ in range(3):
        if w < w_lo or (w == w_lo and T_max <= load):  # on the +T_max limit
            rate = (T_max - load) / J
            if rate > 0.0 and w + rate * left > w_lo:
                left -= (w_lo - w) / rate
                w = w_lo
                continue
            return w + rate * left
        if w > w_hi or (w == w_hi and -T_max >= load):  # on the -T_max limit
            rate = (-T_max - load) / J
            if rate < 0.0 and w + rate * left < w_hi:
                left -= (w_hi - w) / rate
                w = w_hi
                continue
            return w + rate * left
        w_ss = (T_stall - load) / k  # the droop's steady speed under this load
        knee = w_lo if w_ss < w_lo else w_hi if w_ss > w_hi else None
        if knee is not None:
            t_knee = J / k * math.log((w - w_ss) / (knee - w_ss))
            if t_knee < left:
                left -= t_knee
                w = knee
                continue
        return relax(w, T_stall - load, k, J, left)
    return w


class Motor(Fmi2Slave):
    """Rotor inertia with a droop-and-limit torque-speed characteristic."""

    author = "gearpair project"
    description = ("Motor for the GearPair driveline example: rotor inertia driven by "
                   "T_m = clip(T_stall (1 - w/w_noload), -T_max, T_max)")
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

    def _problem(self) -> str | None:
        """A message naming the first parameter or input out of range, or None."""
        for name, causality, unit, _du, lo, hi, _start, _doc in VARIABLES:
            if causality == "output":
                continue
            x = getattr(self, name)
            if not (isinstance(x, float) and math.isfinite(x) and lo <= x <= hi):
                return f"{name} = {x!r} is out of range [{lo:g}, {hi:g}] {unit}"
        return None

    def _update_torque(self) -> None:
        self.torque = characteristic(self.speed, self.T_stall, self.w_noload, self.T_max)

    def exit_initialization_mode(self):
        self.speed = float(self.w_start)
        if self._problem() is None:
            self._update_torque()

    def do_step(self, current_time: float, step_size: float) -> bool:
        try:
            msg = self._problem()
            if msg is None and not step_size > 0.0:
                msg = f"communication step size {step_size!r} must be > 0"
            if msg is not None:
                self.log(f"step refused: {msg}", Fmi2Status.error)
                return False
            self.speed = advance(self.speed, self.load_torque, step_size, self.J,
                                 self.T_stall, self.w_noload, self.T_max)
            self._update_torque()
            return True
        except Exception as e:  # noqa: BLE001 - an exception would be fmi2Fatal
            self.log(f"step failed: {type(e).__name__}: {e}", Fmi2Status.error)
            return False
