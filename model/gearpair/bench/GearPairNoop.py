"""A pythonfmu slave that does nothing, with GearPair's variables.

`gearpair bench` (`gearpair.bench.fmu.build_noop`) copies this script into a temporary folder
next to ``interface.json`` (name, type, causality, start value and description of every
variable of the GearPair.fmu it measures, in value-reference order), builds it with
pythonfmu, runs it on GearPair.fmu's own binary (its C layer and pythonfmu's library, with
its GUID) and drives it with exactly the calls it uses on GearPair.fmu. Its cost is the
plumbing floor that no work in the engine can remove. Like GearPair it hands the C layer a
step block and a compiled step (one that does nothing) when ``stepblock.py`` (the block's
layout, copied beside it by the bench) and numba are there and GEARPAIR_NATIVE_STEP is not
0: the floor is then the C layer's own cost per call; otherwise every call goes through
pythonfmu into Python. Without ``interface.json`` it has only the two inputs. It ships in
the package as a file for pythonfmu to build; nothing imports it.
"""

from __future__ import annotations

import importlib.util
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

        self._handoff = self._native()

    def do_step(self, current_time: float, step_size: float) -> bool:
        return True

    def _native(self) -> tuple[list[int], dict[int, int]]:
        """(block, step, table addresses; value reference -> block slot) for the C layer's
        native step (`GearPair.native_handoff`), or zeros: every call through Python."""
        none = ([0, 0, 0], {})
        where = os.path.join(self.resources or "", "stepblock.py")
        if os.environ.get("GEARPAIR_NATIVE_STEP", "1").strip().lower() in ("0", "off", "no") \
                or not os.path.isfile(where):
            return none
        try:
            import numba
            import numpy as np
        except ImportError:
            return none
        spec = importlib.util.spec_from_file_location("_noop_stepblock", where)
        sb = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sb)
        slot = {"torque": sb.X_TORQUE, "speed": sb.X_SPEED, "load_speed": sb.X_LOAD}
        slot.update((n, sb.X_REC + k) for k, n in enumerate(sb.STEP_RECORD))
        self._block = np.zeros(sb.N_X)
        self._step = numba.cfunc("int64(int64)")(_nothing)  # kept: the C layer calls it
        slots = {vr: slot[v.name] for vr, v in self.vars.items() if v.name in slot}
        return [self._block.ctypes.data, self._step.address, 0], slots

    def get_integer(self, vrs):
        # the C layer's hand-off (value references >= 0x47500000, none in the
        # modelDescription: GearPair.py, `NATIVE_VR`)
        if vrs and vrs[0] >= 0x47500000:
            addresses, slots = self._handoff
            words = [w for a in addresses for w in (a & 0xFFFFFFFF, a >> 32)]
            out = [words[vr - 0x47500000] if vr < 0x47510000 else
                   slots.get(vr - 0x47510000, -1) for vr in vrs]
            return [w - (1 << 32) if w >= 1 << 31 else w for w in out]
        return super().get_integer(vrs)


def _nothing(table):
    return 0
