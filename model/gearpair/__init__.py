"""gearpair: spur gear pair dynamics with time-varying mesh stiffness, tooth separation,
friction and stick-slip (Xun, Dai & Wang 2023). Physics core: no FMI, no plotting."""

import importlib

from .effects import Effects, StiffnessSpec
from .engine import Engine, Outputs, StepSummary
from .equations import Model
from .geometry import Geometry
from .params import RPM, GearParams, OperatingPoint

__all__ = ["RPM", "Effects", "Engine", "GearParams", "Geometry", "Model", "OperatingPoint",
           "Outputs", "StepSummary", "StiffnessSpec", "make_engine"]
__version__ = "0.1.0"


# The engines by name, as data: name -> (module, class), imported on first use (the fast one
# imports numba). Their order is the FMU's engine code: append, never reorder.
ENGINES = {"fast": ("gearpair.fast", "FastEngine"),
           "reference": ("gearpair.reference", "ReferenceEngine")}


def make_engine(params: GearParams | None = None, effects: Effects | None = None,
                engine: str = "fast", **options) -> Engine:
    """Build an engine by name with the given options.

    ``fast`` (the default): numba-compiled stepper (`gearpair.fast.FastEngine`), the
    production path;
    ``reference``: scipy yardstick (`gearpair.reference.ReferenceEngine`).
    """
    try:
        module, cls = ENGINES[engine]
    except (KeyError, TypeError):
        raise ValueError(f"engine = {engine!r}; choose one of: {', '.join(ENGINES)}") from None
    # relative to this package: the FMU imports it under another name
    mod = importlib.import_module(module.replace("gearpair", __name__, 1))
    return getattr(mod, cls)(params, effects, **options)
