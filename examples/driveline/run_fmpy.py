"""Run the driveline SSP with fmpy's SSP simulator (``fmpy.ssp.simulation.simulate_ssp``).

    python examples/driveline/run_fmpy.py build/driveline/driveline.ssp [--stop-time 0.3]

fmpy's simulator is a fixed-step Jacobi master: every FMU steps from the same communication
point with the inputs of the previous point, then all connections are applied. Two things
it does not do itself, handled here:

- it does not apply the SSD's parameter bindings (it only takes a ``parameter_set``
  argument): they are read from the SSD and passed in, typed (its own reader keeps the
  values as strings, and the string ``"false"`` would set a Boolean to true);
- it records each row at the *start* of the step with the values *after* it: the times are
  shifted by one step here, so row i is the state at ``(i + 1) * step``.

It also starts every connection at 0 instead of the outputs' initial values, and applies the
DefaultExperiment of neither the SSD nor the FMUs: the driveline starts from standstill,
where all connected values are 0 anyway, and the stop time and step are arguments.
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
    dict : ``time`` (s, the end of each step on fmpy's accumulated ``t += h``) and every signal of
        `driveline_system.SIGNALS` ("Component.variable", SI units) after each step, as
        arrays of length ``n``
    """
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet

    pset = ParameterSet(name=ds.PARAMETER_SET)
    for comp, values in ds.read_parameters(ssp).items():
        for name, value in values.items():
            p = Parameter(name=f"{comp}.{name}")
            p.value = value
            pset.parameters.append(p)
    n = round(stop_time / step)
    # the loop runs while its accumulated time < stop_time: half a step short gives n steps
    res = simulate_ssp(str(ssp), stop_time=(n - 0.5) * step, step_size=step,
                       parameter_set=pset)
    if len(res) != n:
        raise RuntimeError(f"fmpy made {len(res)} steps instead of {n}")
    out = {"time": np.asarray(res["time"], dtype=float) + step}  # fmpy's own t += h grid
    for sig in ds.SIGNALS:
        out[sig] = np.asarray(res[sig], dtype=float)
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
