"""Run GearPair instances side by side in libcosimpy (libcosim, the OSP co-simulation engine).

    python examples/hosts/run_libcosim.py dist/GearPair.fmu

libcosim counts time in integer nanoseconds: the communication step is ``h_ns``. Start values
(parameters and held inputs) are set with ``real_initial_value``/``integer_initial_value`` by
value reference; a last-value observer reads the outputs after every step.
"""

from __future__ import annotations

import sys

import numpy as np
from hosts_common import INT_OUTPUTS, OUTPUTS, value_references


def run(fmu_path: str, cases: dict[str, dict], h_ns: int, n_steps: int
        ) -> dict[str, dict[str, np.ndarray]]:
    """One instance per case in one execution; outputs after each of ``n_steps`` steps."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    vr = value_references(fmu_path)
    ex = CosimExecution.from_step_size(step_size=int(h_ns))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    index = {}
    for name, case in cases.items():
        i = ex.add_local_slave(CosimLocalSlave(fmu_path=str(fmu_path), instance_name=name))
        index[name] = i
        for var, value in case.items():
            ref, typ = vr[var]
            ok = (ex.real_initial_value(i, ref, float(value)) if typ == "Real"
                  else ex.integer_initial_value(i, ref, int(value)))
            if not ok:
                raise RuntimeError(f"libcosim refused the start value {name}.{var} = {value}")
    real_vrs = [vr[o][0] for o in OUTPUTS]
    int_vrs = [vr[o][0] for o in INT_OUTPUTS]
    rows: dict[str, list] = {name: [] for name in cases}
    for _ in range(n_steps):
        if not ex.step(1):
            raise RuntimeError(f"libcosim step failed: {ex.status()}")
        for name, i in index.items():
            rows[name].append(list(obs.last_real_values(i, real_vrs))
                              + list(obs.last_integer_values(i, int_vrs)))
    out = {}
    for name, r in rows.items():
        a = np.array(r, dtype=float)
        out[name] = {o: a[:, j] for j, o in enumerate(OUTPUTS + INT_OUTPUTS)}
    return out


if __name__ == "__main__":
    fmu = sys.argv[1] if len(sys.argv) > 1 else "dist/GearPair.fmu"
    res = run(fmu, {"a": {"rtol": 1e-6}, "b": {"rtol": 1e-6, "torque": 2500.0}},
              h_ns=100_000, n_steps=20)
    for name, r in res.items():
        print(name, "dte [um]:", np.round(r["dte"][-3:] * 1e6, 4),
              "mesh_force [kN]:", np.round(r["mesh_force"][-3:] * 1e-3, 3))
