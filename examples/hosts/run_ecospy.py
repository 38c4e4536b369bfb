"""Run GearPair instances side by side in ecospy (the Python binding of the ecos engine).

    python examples/hosts/run_ecospy.py dist/GearPair.fmu

Needs the Debian package libtbb12. Start values go in through a parameter set applied at
``init``; variables are addressed as ``instance::name``. ``step(1)`` advances one
communication step (``step_until`` can stop one step short, so steps are counted).
"""

from __future__ import annotations

import sys

import numpy as np
from hosts_common import INT_OUTPUTS, OUTPUTS


def run(fmu_path: str, cases: dict[str, dict], h: float, n_steps: int
        ) -> dict[str, dict[str, np.ndarray]]:
    """One instance per case in one simulation; outputs after each of ``n_steps`` steps."""
    from ecospy.EcosSimulation import EcosSimulation
    from ecospy.EcosSimulationStructure import EcosSimulationStructure

    structure = EcosSimulationStructure()
    for name in cases:
        structure.add_model(name, str(fmu_path))
    start = {f"{name}::{var}": value for name, case in cases.items()
             for var, value in case.items()}
    if start:
        structure.add_parameter_set("start", start)
    sim = EcosSimulation(structure=structure, step_size=h)
    rows: dict[str, list] = {name: [] for name in cases}
    try:
        if not sim.init(parameter_set="start" if start else None):
            raise RuntimeError("ecos could not initialize the simulation")
        for _ in range(n_steps):
            sim.step(1)
            for name in cases:
                rows[name].append([sim.get_real(f"{name}::{o}") for o in OUTPUTS]
                                  + [sim.get_integer(f"{name}::{o}") for o in INT_OUTPUTS])
        sim.terminate()
    finally:
        sim.free()
        structure.free()
    out = {}
    for name, r in rows.items():
        a = np.array(r, dtype=float)
        out[name] = {o: a[:, j] for j, o in enumerate(OUTPUTS + INT_OUTPUTS)}
    return out


if __name__ == "__main__":
    fmu = sys.argv[1] if len(sys.argv) > 1 else "dist/GearPair.fmu"
    res = run(fmu, {"a": {"rtol": 1e-6}, "b": {"rtol": 1e-6, "torque": 2500.0}},
              h=1e-4, n_steps=20)
    for name, r in res.items():
        print(name, "dte [um]:", np.round(r["dte"][-3:] * 1e6, 4),
              "mesh_force [kN]:", np.round(r["mesh_force"][-3:] * 1e-3, 3))
