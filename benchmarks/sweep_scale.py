"""Scale figures of `gearpair sweep` (the tables of docs/sweep.md "Scale").

1. A grid at the paper's settings (default: 40 speeds x 5 torques x 5 friction coefficients
   = 1,000 points, `SweepSettings()` defaults) on a local cluster of ``--workers`` processes,
   into a fresh store: wall time, points per minute, CPU time per point, the peak memory of
   the client and of each worker, the store's size.
2. The cost per task that does not shrink with more workers: dask's scheduling round trip
   (many no-op tasks), and the client's store write per point (both serial on the client),
   plus a sweep of many short points to see them together.

Usage (from the repository root; write a free ``--dir``; under the suite lock on a shared
machine)::

    .venv/bin/python benchmarks/sweep_scale.py --dir build/scale
    .venv/bin/python benchmarks/sweep_scale.py --grid speed_rpm=5:600:10 mu=0.01,0.03 --dir /tmp/s

Prints a table and writes ``DIR/scale.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

DEFAULT_GRID = ["speed_rpm=5:600:40", "torque=1000:4000:5", "mu=0.01:0.05:5"]


def _peak_rss_mb() -> float:
    """Peak resident memory of this process (MB; Linux reports KB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _store_size(path: Path) -> dict[str, float]:
    files = [p for p in path.rglob("*") if p.is_file()]
    du = subprocess.run(["du", "-sk", str(path)], capture_output=True, text=True)
    return {"files": len(files), "bytes_mb": sum(p.stat().st_size for p in files) / 1e6,
            "disk_mb": int(du.stdout.split()[0]) / 1024.0 if du.returncode == 0 else None}


def _noop(x):
    return x


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", nargs="+", default=DEFAULT_GRID, metavar="NAME=VALUES")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--dir", default="build/scale", help="scratch folder (stores)")
    ap.add_argument("--short-points", type=int, default=400,
                    help="points of the short-point sweep (overhead); 0 skips it")
    ap.add_argument("--noop-tasks", type=int, default=2000)
    args = ap.parse_args(argv)

    from dask.distributed import Client

    from gearpair.sweep import Grid, SweepSettings, local_cluster, run_grid
    from gearpair.sweep.point import run_point
    from gearpair.sweep.store import Store

    out = Path(args.dir)
    out.mkdir(parents=True, exist_ok=True)
    res: dict = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                 "load_before": os.getloadavg(), "cores": os.cpu_count(),
                 "workers": args.workers, "grid": args.grid}
    with local_cluster(args.workers) as addr:
        client = Client(addr)
        # -- 1. the grid at the paper's settings ---------------------------------------------
        grid = Grid.parse(args.grid)
        store = out / "grid.zarr"
        if store.exists():
            shutil.rmtree(store)
        t0 = time.perf_counter()
        run = run_grid(grid, SweepSettings(), store, scheduler=addr, progress=True)
        wall = time.perf_counter() - t0
        s = run.summary()
        peaks = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        res["grid_run"] = {
            "points": grid.size, "ok": s["ok"], "failed": s["failed"], "invalid": s["invalid"],
            "wall_s": round(wall, 1), "compute_s": s["elapsed_s"], "startup_s": s["startup_s"],
            "points_per_min": s["points_per_min"], "cpu_s_per_point": s["cpu_s_per_point"],
            "speedup_over_one_core": s["speedup_over_one_core"],
            "client_peak_rss_mb": round(_peak_rss_mb(), 1),
            "worker_peak_rss_mb": sorted(round(v, 1) for v in peaks.values()),
            "store": {k: round(v, 2) if isinstance(v, float) else v
                      for k, v in _store_size(store).items()},
            "load_after": os.getloadavg()}
        # -- 2. per-task costs that do not shrink with workers --------------------------------
        t0 = time.perf_counter()
        futs = client.map(_noop, range(args.noop_tasks), pure=False)
        client.gather(futs)
        del futs
        res["noop_task_ms"] = round(1e3 * (time.perf_counter() - t0) / args.noop_tasks, 3)
        quick = SweepSettings(transient_periods=10, transient_time=0.0, kept_periods=10,
                              max_time=0.5, min_periods=4)
        g1 = Grid.parse(["mu=0.01,0.02", "speed_rpm=100,150"])
        scratch = out / "write.zarr"
        if scratch.exists():
            shutil.rmtree(scratch)
        st = Store.open_or_create(scratch, g1, quick)
        recs = [run_point(i, g1.names, tuple(p.values()), quick) for i, p in g1.points()]
        t0 = time.perf_counter()
        n = 0
        for _ in range(25):
            for r in recs:
                st.write(r)
                n += 1
        res["store_write_ms"] = round(1e3 * (time.perf_counter() - t0) / n, 2)
        if args.short_points:
            gs = Grid.product({"mu": [0.01 + 0.04 * k / args.short_points
                                      for k in range(args.short_points)]})
            short = out / "short.zarr"
            if short.exists():
                shutil.rmtree(short)
            run = run_grid(gs, quick, short, scheduler=addr, progress=False)
            ss = run.summary()
            ds_wall = sum(r["wall_s"] for r in Store.open(short).records())
            res["short_run"] = {
                "points": gs.size, "compute_s": ss["elapsed_s"],
                "point_wall_ms": round(1e3 * ds_wall / gs.size, 2),
                "per_point_ms": round(1e3 * ss["elapsed_s"] / gs.size, 2),
                "overhead_ms_per_point": round(
                    1e3 * (ss["elapsed_s"] * args.workers - ds_wall) / gs.size, 2)}
        client.close()
    res["load_end"] = os.getloadavg()
    (out / "scale.json").write_text(json.dumps(res, indent=2))
    g = res["grid_run"]
    print(f"\n{res['date']}, {res['cores']} cores, {args.workers} workers, load before "
          f"{res['load_before'][0]:.1f}, after {g['load_after'][0]:.1f}")
    rows = [("points (ok/failed/invalid)", f"{g['points']} ({g['ok']}/{g['failed']}/"
             f"{g['invalid']})"),
            ("wall time, whole run (s)", g["wall_s"]), ("computation (s)", g["compute_s"]),
            ("start-up (s)", g["startup_s"]), ("points per minute", g["points_per_min"]),
            ("CPU time per point (s)", g["cpu_s_per_point"]),
            ("speed-up over one core", g["speedup_over_one_core"]),
            ("client peak RSS (MB)", g["client_peak_rss_mb"]),
            ("worker peak RSS (MB)", ", ".join(map(str, g["worker_peak_rss_mb"]))),
            ("store: files, bytes (MB), on disk (MB)",
             f"{g['store']['files']}, {g['store']['bytes_mb']}, {g['store']['disk_mb']}"),
            ("dask no-op task, round trip (ms)", res["noop_task_ms"]),
            ("store write per point, client (ms)", res["store_write_ms"])]
    if "short_run" in res:
        r = res["short_run"]
        rows.append((f"{r['points']} short points: ms per point / point's own ms / overhead "
                     "ms per point x workers",
                     f"{r['per_point_ms']} / {r['point_wall_ms']} / "
                     f"{r['overhead_ms_per_point']}"))
    for k, v in rows:
        print(f"| {k} | {v} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
