"""The GearPair FMU as an engine: the start values that set it up as a scene, and a run
through fmpy as an FMI 2.0 co-simulation master drives it."""

from __future__ import annotations

import math
import time as _time
from dataclasses import fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import ENGINES
from ..effects import OPTIONS, Effects
from ..params import GearParams
from ..results import Trajectory
from .driver import FmuDriver
from .errors import SceneError
from .location import find_fmu

if TYPE_CHECKING:
    from .types import Scene


def fmu_start_values(scene: Scene, variables: dict[str, Any]) -> dict[str, Any]:
    """Start values that set the FMU up as the scene (``variables``: name -> fmpy variable).

    The effects' parameters, codes and the "not given" 0 come from their metadata
    (`gearpair.effects.OPTIONS`), the one declaration the FMU's parameters are made from.
    Raises `SceneError` when the scene calls for something the FMU cannot express.
    """
    fx = scene.effects

    def refuse(what: str) -> SceneError:
        return SceneError(f"the FMU cannot express {what}; run this scene with --engine fast "
                          "or reference")

    if not scene.solver.static_start:
        raise refuse("[solver] static_start = false (it always starts from static equilibrium)")
    start: dict[str, Any] = {f.name: getattr(scene.params, f.name) for f in fields(GearParams)}
    if fx.stiffness.kind == "table":
        raise refuse("[effects.stiffness] kind = \"table\"")
    defaults = Effects().values()
    for name, value in fx.values().items():
        m = OPTIONS[name]
        param = m["fmu"]
        if value is None:
            continue  # not given: the FMU's start value 0 codes None
        if param not in variables:
            if value == defaults[name]:
                continue  # an FMU from before this parameter runs it this way
            raise refuse(f"[effects] {name} = {value!r} (no parameter {param!r})")
        if m["kind"] == "choice":
            start[param] = m["fmu_choices"].index(value)
        else:
            start[param] = bool(value) if m["kind"] == "bool" else float(value)
    start["rtol"] = float(scene.solver.rtol)
    if "engine" in variables:
        start["engine"] = tuple(ENGINES).index("fast")
    missing = sorted(k for k in start if k not in variables)
    if missing:
        raise refuse(f"the parameter(s) {', '.join(missing)} (not in this FMU)")
    return start


def run_fmu(scene: Scene, fmu_path: str | Path | None = None) -> Trajectory:
    """Run the scene through the GearPair FMU with fmpy at the scene's communication step.

    The FMU is driven as an FMI 2.0 co-simulation master drives it (fmpy's ``FMU2Slave``):
    inputs set at each communication point and held over the step (the values `simulate`
    holds), then ``doStep``. The trajectory's ``meta`` has ``startup_s`` (extracting and
    instantiating the FMU and its initialization, where it builds the engine and loads the
    compiled code) apart from ``wall_time_s`` (the steps and the reading of the outputs).
    """
    try:
        import fmpy  # noqa: F401
    except ImportError:
        raise SceneError("--engine fmu needs fmpy: pip install 'gearpair[fmu]'") from None

    path = find_fmu(fmu_path)
    wall0 = _time.perf_counter()
    drv = FmuDriver(path)
    fmu = None
    t = 0.0
    try:
        variables = drv.variables
        start = fmu_start_values(scene, variables)
        outputs = drv.outputs()
        reals = [n for n in outputs if variables[n].type == "Real"]
        others = [n for n in outputs if variables[n].type != "Real"]
        h, t_end = scene.step, scene.t_end
        n = int(math.ceil(t_end / h - 1e-9))
        grid = np.minimum(h * np.arange(n + 1), t_end)  # the communication points
        grid[-1] = t_end
        fT, fW = scene.inputs.torque, scene.inputs.speed
        # a scene drives no load shaft: load_speed stays 0 with load_speed_input false
        names_in = [k for k in ("torque", "speed", "load_speed") if k in variables]
        vr_in, vr_real, vr_other = drv.refs(names_in), drv.refs(reals), drv.refs(others)
        rec = np.zeros((n + 1, len(outputs)))

        def held(t):
            return [float(fT(t)), float(fW(t)), 0.0][:len(vr_in)]

        def read(i):
            rec[i, :len(reals)] = fmu.getReal(vr_real)
            if vr_other:
                rec[i, len(reals):] = fmu.getInteger(vr_other)

        try:
            fmu = drv.instance()
            drv.initialize(fmu, start, dict(zip(names_in, held(0.0), strict=True)))
            startup = _time.perf_counter() - wall0
            wall0 = _time.perf_counter()
            read(0)
            for i in range(1, n + 1):
                t = float(grid[i - 1])
                fmu.setReal(vr_in, held(t))
                fmu.doStep(currentCommunicationPoint=t,
                           communicationStepSize=float(grid[i]) - t)
                read(i)
            wall = _time.perf_counter() - wall0
            fmu.terminate()
        except Exception as exc:  # fmpy reports a refused call as a generic exception
            msg = (f"FMU run of scene {scene.name!r} failed at t = {t:g} s: {exc} (rerun "
                   "with fmpy's debug_logging for the FMU's message)")
            raise RuntimeError(msg) from exc
    finally:
        if fmu is not None:
            fmu.freeInstance()
        drv.close()
    data: dict[str, np.ndarray] = {"time": grid.astype(float)}
    for k, name in enumerate(reals + others):
        data[name] = rec[:, k]
    # As `simulate` records: row i holds the inputs held over the interval ending at t[i].
    held = np.concatenate([grid[:1], grid[:-1]])
    data["torque"] = np.array([fT(x) for x in held])
    data["speed"] = np.array([fW(x) for x in held])
    data["load_speed"] = data["speed"] * scene.params.ratio  # nominal, as in `simulate`
    return Trajectory(data, {"engine": "fmu", "wall_time_s": wall, "startup_s": startup,
                             "fmu": str(path)})
