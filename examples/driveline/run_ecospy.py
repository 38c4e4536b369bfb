"""Run the driveline SSP with ecospy (the Python binding of the ecos co-simulation engine).

    python examples/driveline/run_ecospy.py build/driveline/driveline.ssp [--stop-time 0.3]

Needs the Debian package libtbb12. ``EcosSimulation(ssp_path=..., step_size=...)`` loads the
archive; the inline parameter bindings form named parameter sets, applied only when
``init`` is given the set's name (`driveline_system.PARAMETER_SET`). Its fixed-step
algorithm is a Jacobi master like fmpy's and libcosim's. Steps are counted with
``step(1)`` (``step_until`` can stop one step short); variables are "instance::name".
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import driveline_system as ds  # noqa: E402


def run(ssp: str | Path, stop_time: float, step: float) -> dict[str, np.ndarray]:
    """Simulate the SSP for ``n = round(stop_time / step)`` communication steps.

    Parameters
    ----------
    ssp : the ``.ssp`` archive written by build.py
    stop_time : s, end of the run
    step : s, communication step

    Returns
    -------
    dict : ``time`` (s, the end of each step on ecos's accumulated ``t += h``) and every signal of
        `driveline_system.SIGNALS` ("Component.variable", SI units) after each step, as
        arrays of length ``n``
    """
    from ecospy.EcosSimulation import EcosSimulation

    sim = EcosSimulation(ssp_path=str(ssp), step_size=step)
    ids = [sig.replace(".", "::", 1) for sig in ds.SIGNALS]
    getters = [sim.get_integer if sig in ds.INTEGER_SIGNALS else sim.get_real
               for sig in ds.SIGNALS]
    n = round(stop_time / step)
    rows = np.empty((n, len(ids)))
    times = np.empty(n)
    try:
        if not sim.init(parameter_set=ds.PARAMETER_SET):
            raise RuntimeError("ecos could not initialize the simulation")
        for k in range(n):
            times[k] = sim.step(1)
            rows[k] = [get(i) for get, i in zip(getters, ids, strict=True)]
        sim.terminate()
    finally:
        sim.free()
    out = {"time": times}
    for j, sig in enumerate(ds.SIGNALS):
        out[sig] = rows[:, j]
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("ssp", nargs="?", default=str(HERE.parents[1] / "build" / "driveline"
                                                  / "driveline.ssp"))
    ap.add_argument("--stop-time", type=float, default=0.3, help="s")
    ap.add_argument("--step", type=float, default=1e-4, help="communication step, s")
    a = ap.parse_args()
    r = run(a.ssp, a.stop_time, a.step)
    print(f"t = {r['time'][-1]:g} s: motor {r['Motor.speed'][-1] / ds.RPM:.2f} r/min, "
          f"output torque {r['GearPair.output_torque'][-1]:.1f} N.m, "
          f"DTE {r['GearPair.dte'][-1] * 1e6:.3f} um", flush=True)
