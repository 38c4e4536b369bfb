"""A GearPair FMU instance through fmpy's FMI 2.0 API that keeps what it logs (test helper)."""

from __future__ import annotations

from ctypes import byref

from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2CoSimulation,
    fmi2False,
    fmi2True,
    free,
)


class LoggingSlave:
    """An instantiated FMU2Slave (debug logging on unless ``logging_on`` is false) on an
    extracted FMU; ``messages`` holds (status, text) of every log call and ``vr`` maps names
    to value references."""

    def __init__(self, md, unzipdir: str, name: str = "gp", logging_on: bool = True,
                 resource_location: str | None = None) -> None:
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
        if resource_location is None:
            self.fmu.instantiate(callbacks=cb, loggingOn=logging_on)
        else:  # a resource location of the caller's form (fmpy writes file:///abs)
            self.fmu.callbacks = cb
            self.fmu.component = self.fmu.fmi2Instantiate(
                name.encode(), fmi2CoSimulation, md.guid.encode(), resource_location.encode(),
                byref(cb), fmi2False, fmi2True if logging_on else fmi2False)
            if self.fmu.component is None:
                raise RuntimeError(f"fmi2Instantiate failed: {self.messages}")

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
