"""gearpair: spur gear pair dynamics with time-varying mesh stiffness, tooth separation,
friction and stick-slip (Xun, Dai & Wang 2023). Physics core: no FMI, no plotting."""

from .effects import Effects, StiffnessSpec
from .engine import Engine, Outputs, StepSummary
from .equations import Model
from .geometry import Geometry
from .params import RPM, GearParams, OperatingPoint

__all__ = ["RPM", "Effects", "Engine", "GearParams", "Geometry", "Model", "OperatingPoint",
           "Outputs", "StepSummary", "StiffnessSpec", "make_engine"]
__version__ = "0.1.0"


def make_engine(params: GearParams | None = None, effects: Effects | None = None,
                engine: str = "fast", **options) -> Engine:
    """Build an engine by name with the given options.

    ``fast`` (the default): numba-compiled stepper (`gearpair.fast.FastEngine`), the
    production path;
    ``reference``: scipy yardstick (`gearpair.reference.ReferenceEngine`).
    """
    if engine == "reference":
        from .reference import ReferenceEngine

        return ReferenceEngine(params, effects, **options)
    if engine == "fast":
        from .fast import FastEngine

        return FastEngine(params, effects, **options)
    raise ValueError(f"engine = {engine!r}; choose one of: fast, reference")
