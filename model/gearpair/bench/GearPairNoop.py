"""A pythonfmu slave that does nothing, with GearPair's variables.

`gearpair bench` (`gearpair.bench.fmu.build_noop`) copies this script into a temporary folder
next to ``interface.json`` (name, type, causality, start value and description of every
variable of the GearPair.fmu it measures, in value-reference order) and builds it with
pythonfmu for its modelDescription: GearPair's variables, value references and (set by the
bench) GUID. The no-op FMU's binary is then the FMU's generic FMI layer over a model that
does nothing (``fmu_src/c/noop_fmu.c``), which the bench drives with exactly the calls it
uses on GearPair.fmu: its cost is the plumbing floor that no work in the engine can remove.
Without ``interface.json`` it has only the two inputs. It ships in the package as a file for
pythonfmu to build; nothing imports it.
"""

from __future__ import annotations

import json
import os

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability
from pythonfmu.enums import Fmi2Initial
from pythonfmu.variables import Boolean, Integer, Real

_TYPES = {"Real": (Real, float), "Integer": (Integer, int), "Boolean": (Boolean, bool)}
_INPUTS = [{"name": "torque", "type": "Real", "causality": "input",
            "variability": "continuous", "start": 3900.0},
           {"name": "speed", "type": "Real", "causality": "input",
            "variability": "continuous", "start": 10.471975511965978}]


def _interface(resources: str | None) -> list[dict]:
    for folder in (resources, os.path.dirname(os.path.abspath(__file__))):
        path = os.path.join(folder or "", "interface.json")
        if folder and os.path.isfile(path):
            with open(path, encoding="utf-8") as fh:
                return json.load(fh)
    return _INPUTS


class GearPairNoop(Fmi2Slave):
    """GearPair's interface with an empty step."""

    author = "gearpair project"
    description = "Do-nothing slave with GearPair's variables (benchmark plumbing floor)"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for v in _interface(self.resources):
            cls, cast = _TYPES[v["type"]]
            start = v.get("start")
            setattr(self, v["name"], cast(start) if start is not None else cast(0))
            kw = {"causality": getattr(Fmi2Causality, v["causality"]),
                  "variability": getattr(Fmi2Variability, v["variability"]),
                  "description": v.get("description")}
            if v["causality"] == "parameter":
                kw["initial"] = Fmi2Initial.exact
            self.register_variable(cls(v["name"], **kw))

    def do_step(self, current_time: float, step_size: float) -> bool:
        return True
