"""A GearPair FMU instance through fmpy's FMI 2.0 API that keeps what it logs (test helper)."""

from __future__ import annotations

from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    free,
)


class LoggingSlave:
    """An instantiated FMU2Slave (debug logging on unless ``logging_on`` is false) on an
    extracted FMU; ``messages`` holds (status, text) of every log call and ``vr`` maps names
    to value references."""

    def __init__(self, md, unzipdir: str, name: str = "gp", logging_on: bool = True) -> None:
        self.md = md
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.messages: list[tuple[int, str]] = []

        def logger(env, instance, status, category, message):
            self.messages.append((status, message.decode("utf-8", "replace")))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._cb = cb  # keep the ctypes callbacks alive
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(callbacks=cb, loggingOn=logging_on)

    def set(self, **values) -> None:
        """fmi2Set* by name: a bool as Boolean, an int as Integer, anything else as Real."""
        for name, value in values.items():
            vr = [self.vr[name]]
            if isinstance(value, bool):
                self.fmu.setBoolean(vr, [value])
            elif isinstance(value, int):
                self.fmu.setInteger(vr, [value])
            else:
                self.fmu.setReal(vr, [float(value)])
