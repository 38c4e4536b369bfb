"""Worker scaling of `gearpair sweep` on this machine (the table of docs/sweep.md).

Runs the same sweep (default: 40 speeds over 110-600 r/min, stick-slip model, default
settings, so every point costs about the same) on a fresh local cluster of 1, 2, ... worker
processes and prints a Markdown table: start-up, computation time, throughput, speed-up over
one worker, parallel efficiency (wall time of the points / (workers x computation time)),
CPU time per point and the CPU share (CPU time / wall time of the points: below 1 when the
workers wait for a core that other processes use).

    python examples/paper/scaling.py [--workers 1,2,3,4] [--points 40]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from gearpair.sweep import SweepSettings, run_sweep


def measure(workers: list[int], points: int) -> list[dict]:
    values = np.linspace(110.0, 600.0, points)
    rows = []
    for n in workers:
        load = os.getloadavg()[0]
        res = run_sweep("speed_rpm", values, SweepSettings(), workers=n, progress=False)
        s = res.summary()
        rows.append({"workers": n, "startup_s": s["startup_s"], "elapsed_s": s["elapsed_s"],
                     "throughput": s["throughput_points_per_s"], "efficiency": s["efficiency"],
                     "failed": len(s["failed"]), "load_before": load,
                     "cpu_share": s["cpu_share"],
                     "cpu_per_point": s["point_cpu_s"] / len(values)})
    base = rows[0]["throughput"] / rows[0]["workers"]
    for r in rows:
        r["speedup"] = r["throughput"] / base
    return rows


def table(rows: list[dict], points: int) -> str:
    head = (f"{points} points, {time.strftime('%Y-%m-%d')}, {platform.machine()}, "
            f"{os.cpu_count()} CPUs, Python {platform.python_version()}\n\n"
            "| workers | start-up (s) | computation (s) | points/s | speed-up | efficiency "
            "| CPU per point (s) | CPU share | load average before |\n"
            "|---|---|---|---|---|---|---|---|---|")
    lines = [f"| {r['workers']} | {r['startup_s']:.1f} | {r['elapsed_s']:.1f} | "
             f"{r['throughput']:.3f} | {r['speedup']:.2f} | {r['efficiency']:.2f} | "
             f"{r['cpu_per_point']:.2f} | {r['cpu_share']:.2f} | {r['load_before']:.1f} |"
             for r in rows]
    return "\n".join([head, *lines])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", default="1,2,3,4")
    ap.add_argument("--points", type=int, default=40)
    a = ap.parse_args(argv)
    ws = [int(w) for w in a.workers.split(",")]
    print(table(measure(ws, a.points), a.points))


if __name__ == "__main__":
    main()
