"""Shared helpers of the host examples: the case description and the fmpy run to compare with.

A *case* is a dict of start values (parameters and held inputs) for one GearPair instance,
e.g. ``{"rtol": 1e-6, "torque": 2500.0}``. Every host runs a case with a fixed communication
step ``h`` from 0 to ``n_steps * h`` and returns, per recorded output, the values after each
step (row i is the value at ``(i + 1) * h``).
"""

from __future__ import annotations

import numpy as np

OUTPUTS = ("dte", "mesh_force", "friction_force", "gear1_speed", "gear2_speed",
           "sliding_velocity")
INT_OUTPUTS = ("contact_state",)


def value_references(fmu_path: str) -> dict[str, tuple[int, str]]:
    """Name -> (value reference, type) from the FMU's modelDescription."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu_path))
    return {v.name: (v.valueReference, v.type) for v in md.modelVariables}


def run_fmpy(fmu_path: str, case: dict, h: float, n_steps: int) -> dict[str, np.ndarray]:
    """The same case through `fmpy.simulate_fmu` (output interval = communication step)."""
    import fmpy

    res = fmpy.simulate_fmu(str(fmu_path), stop_time=n_steps * h, output_interval=h,
                            start_values=dict(case), output=list(OUTPUTS + INT_OUTPUTS))
    return {name: np.asarray(res[name][1:], dtype=float) for name in OUTPUTS + INT_OUTPUTS}
