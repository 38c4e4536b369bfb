"""Run the driveline SSP with libcosimpy (libcosim, the Open Simulation Platform engine).

    python examples/driveline/run_libcosim.py build/driveline/driveline.ssp [--stop-time 0.3]

``CosimExecution.from_ssp_file`` loads the archive, the connections and the first parameter
set of every component (the inline bindings). libcosim's fixed-step algorithm is a Jacobi
master like fmpy's; it counts time in integer nanoseconds, so the step must be a whole
number of nanoseconds. A last-value observer reads the outputs after each step.
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
    dict : ``time`` (s, the end of each step on libcosim's integer nanoseconds) and every signal of
        `driveline_system.SIGNALS` ("Component.variable", SI units) after each step, as
        arrays of length ``n``
    """
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    step_ns = round(step * 1e9)
    if abs(step_ns - step * 1e9) > 1e-6 * step * 1e9:
        raise ValueError(f"libcosim needs a whole number of nanoseconds, not {step!r} s")
    log_output_level(CosimLogLevel.WARNING)
    ex = CosimExecution.from_ssp_file(str(ssp), step_size=step_ns)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    slaves = {info.name.decode(): info.index for info in ex.slave_infos()}
    refs = {comp: {v.name.decode(): v.reference for v in ex.slave_variables(i)}
            for comp, i in slaves.items()}
    reals = [s for s in ds.SIGNALS if s not in ds.INTEGER_SIGNALS]
    ints = [s for s in ds.SIGNALS if s in ds.INTEGER_SIGNALS]

    def read(sigs, getter):
        vals = []
        for sig in sigs:
            comp, name = sig.split(".", 1)
            vals.append(getter(slaves[comp], [refs[comp][name]])[0])
        return vals

    n = round(stop_time / step)
    rows = np.empty((n, len(reals) + len(ints)))
    times = np.empty(n)
    for k in range(n):
        if not ex.step(1):
            raise RuntimeError(f"libcosim step {k} failed: {ex.status()}")
        times[k] = ex.status().current_time * 1e-9  # integer nanoseconds
        rows[k, :len(reals)] = read(reals, obs.last_real_values)
        rows[k, len(reals):] = read(ints, obs.last_integer_values)
    out = {"time": times}
    for j, sig in enumerate(reals + ints):
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
