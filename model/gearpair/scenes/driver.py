"""Driving an FMI 2.0 co-simulation FMU with fmpy as a master does: read its model
description, extract it, instantiate, set start values by type, initialize.

`gearpair.scenes.fmu.run_fmu` runs scenes with it, and the benchmark (`gearpair.bench.fmu`)
times FMUs with it in child processes that must never import this package (an FMU imports
its own bundled copy, as in any host). So this module imports nothing of gearpair, only the
standard library and fmpy (when used), and the benchmark runs its text (`source`).
"""

from __future__ import annotations

import shutil
from pathlib import Path


class FmuDriver:
    """One FMU file: its model description (``md``), variables by name (``variables``) and
    extracted folder (``unzip``), shared by the instances it makes.

    Parameters
    ----------
    path : the ``.fmu`` file
    unzipdir : where to extract it; default a temporary folder that `close` removes
    """

    def __init__(self, path: str | Path, unzipdir: str | Path | None = None) -> None:
        import fmpy

        self.path = str(path)
        self.md = fmpy.read_model_description(self.path)
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.unzip = fmpy.extract(self.path, unzipdir=None if unzipdir is None
                                  else str(unzipdir))
        self._owned = unzipdir is None

    def outputs(self) -> list[str]:
        """Names of the output variables, in the model description's order."""
        return [v.name for v in self.md.modelVariables if v.causality == "output"]

    def refs(self, names) -> list[int]:
        """Value references of ``names``."""
        return [self.variables[n].valueReference for n in names]

    def instance(self, name: str = "gearpair"):
        """A new instantiated ``fmpy.fmi2.FMU2Slave`` of this FMU."""
        from fmpy.fmi2 import FMU2Slave

        fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzip, instanceName=name,
                        modelIdentifier=self.md.coSimulation.modelIdentifier)
        fmu.instantiate()
        return fmu

    def set_values(self, fmu, values: dict) -> None:
        """Set variables by name, each with the setter of its type (Real, Integer,
        Boolean)."""
        for name, x in values.items():
            v = self.variables[name]
            if v.type == "Real":
                fmu.setReal([v.valueReference], [float(x)])
            elif v.type == "Integer":
                fmu.setInteger([v.valueReference], [int(x)])
            elif v.type == "Boolean":
                fmu.setBoolean([v.valueReference], [bool(x)])
            else:
                raise TypeError(f"{name}: cannot set a {v.type} variable")

    def initialize(self, fmu, start: dict, inputs: dict | None = None) -> None:
        """Start at t = 0 with the ``start`` values, set ``inputs`` in initialization mode
        (the values held over the first step), and leave it."""
        fmu.setupExperiment(startTime=0.0)
        self.set_values(fmu, start)
        fmu.enterInitializationMode()
        if inputs:
            self.set_values(fmu, inputs)
        fmu.exitInitializationMode()

    def close(self) -> None:
        """Remove the extracted folder if this driver made it."""
        if self._owned:
            shutil.rmtree(self.unzip, ignore_errors=True)


def source() -> str:
    """This module's text, for a child process that must not import gearpair."""
    return Path(__file__).read_text()
