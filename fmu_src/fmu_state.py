"""The slave's FMU state as bytes: a pickle of plain data read back by a restricted unpickler
that admits only plain data, numpy arrays and gearpair classes (never functions), so that a
crafted state cannot run code. Ships in the FMU's resources beside the slave.
"""

from __future__ import annotations

import io
import pickle

STATE_FORMAT = "gearpair-fmu-state/1"
BUNDLE = "_gearpair_fmu"  # the bundled package's import name (fmu_bundle.BUNDLE)


class _StateUnpickler(pickle.Unpickler):
    """Unpickler for serialized FMU states: plain data, numpy arrays and gearpair classes."""

    _ALLOWED = {
        ("builtins", "set"), ("builtins", "frozenset"), ("builtins", "complex"),
        ("builtins", "slice"), ("builtins", "range"), ("builtins", "bytearray"),
        ("collections", "OrderedDict"),
        ("numpy", "dtype"), ("numpy", "ndarray"),
        ("numpy._core.numeric", "_frombuffer"), ("numpy.core.numeric", "_frombuffer"),
        ("numpy._core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "scalar"), ("numpy.core.multiarray", "scalar"),
    }

    def __init__(self, file, package: str) -> None:
        super().__init__(file)
        self._package = package  # name of the gearpair package the slave runs

    def find_class(self, module: str, name: str):
        if (module, name) in self._ALLOWED:
            return super().find_class(module, name)
        top, dot, rest = module.partition(".")
        if top in ("gearpair", BUNDLE):  # either import name: the package this slave runs
            module = self._package + dot + rest
        if module == "numpy.dtypes" or module.partition(".")[0] == self._package:
            obj = super().find_class(module, name)
            if isinstance(obj, type):  # classes only, never functions
                return obj
        raise pickle.UnpicklingError(f"FMU state refers to {module}.{name}, which is not allowed")


def _loads_state(data: bytes, package: str = "gearpair") -> dict:
    state = _StateUnpickler(io.BytesIO(data), package).load()
    if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
        raise ValueError("not a GearPair FMU state")
    return state
