"""Peak memory of a long recorded run, in a child process."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

from .settings import TARGET_MEMORY_MB

_MEMORY_CHILD = r"""
import json, resource, sys, time

def peak_kb():
    # VmHWM: the peak of this process's own memory. getrusage's ru_maxrss is not that on
    # Linux: across fork + exec it keeps the parent's peak (a test session holding two
    # compiled engines read as this child's).
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / 1024 if sys.platform == "darwin" else kb  # bytes there

from gearpair.results import simulate
from gearpair.fast import FastEngine
FastEngine()  # load the compiled kernels before the baseline
base = peak_kb()
t0 = time.perf_counter()
traj = simulate(t_end=float(sys.argv[1]), dt=float(sys.argv[2]), engine="fast")
wall = time.perf_counter() - t0
peak = peak_kb()
data = sum(v.nbytes for v in traj.data.values())
print(json.dumps({"baseline_kb": base, "peak_kb": peak, "wall_s": wall,
                  "samples": len(traj.time), "trajectory_bytes": data}))
"""


def memory_peak(t_end: float = 100.0, dt: float = 1e-4) -> dict:
    """Peak RSS of ``simulate(t_end, dt, engine="fast")`` (stick-slip default point) in a
    child process (its own high-water mark, ``VmHWM``; ``getrusage`` where there is no
    ``/proc``)."""
    env = dict(os.environ)
    # the child imports the gearpair this process runs: the sys.path entry it came from
    # (site-packages, or a checkout's model/ folder) goes first
    entry = Path(importlib.util.find_spec("gearpair").origin).parent.parent
    env["PYTHONPATH"] = os.pathsep.join([str(entry), *filter(None, [env.get("PYTHONPATH")])])
    proc = subprocess.run([sys.executable, "-c", _MEMORY_CHILD, repr(t_end), repr(dt)],
                          capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"memory run failed: {proc.stderr[-2000:]}")
    d = json.loads(proc.stdout.strip().splitlines()[-1])
    peak = d["peak_kb"] / 1024.0
    return {"t_end": t_end, "dt": dt, "samples": d["samples"], "wall_s": d["wall_s"],
            "peak_rss_mb": peak, "baseline_rss_mb": d["baseline_kb"] / 1024.0,
            "trajectory_mb": d["trajectory_bytes"] / 2**20, "target_mb": TARGET_MEMORY_MB,
            "met": peak <= TARGET_MEMORY_MB}

