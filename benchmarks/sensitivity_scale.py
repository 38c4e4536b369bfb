"""A 10,000-evaluation Sobol study on a local dask cluster (issue 36 item 5; docs/sweep.md).

1. ``run_sensitivity`` over mu, torque, speed and the mean mesh stiffness (the paper's
   stick-slip model, `SweepSettings()` defaults: 100 discarded mesh periods, at least 1 s,
   100 kept, about 6 s simulated at most), Sobol with second-order indices at n = 1024:
   n (2D + 2) = 10,240 evaluations, on a local cluster of ``--workers`` single-threaded
   processes, into a new store. Measured: the wall time (the study: start-up, points,
   indices), evaluations per minute, the CPU time per point, the peak memory of the client
   (which runs the scheduler too) and of each worker, the store's size, the time of the
   analysis (SALib, bootstrap intervals).
2. The costs that do not shrink with more workers, for the extrapolation: dask's round trip
   per task (no-op tasks) and the client's store write per point, one at a time and in a
   batch of 256 (results that arrive together are written together).
3. From these, what 1e6 evaluations would take on N machines of this size (docs/sweep.md).

Usage (from the repository root)::

    .venv/bin/python benchmarks/sensitivity_scale.py --dir build/sa_scale

Prints a table and writes ``DIR/sensitivity_scale.json``; the indices are in the store
(``gearpair.sweep.open_indices(DIR/sobol.zarr)``) and drawn in ``DIR/sobol.png``.
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

RANGES = ["mu=0.005:0.05", "torque=500:4000", "speed_rpm=20:600", "km_mean=3e9:5e9"]
OUTPUTS = ("stick_ratio", "contact_loss_ratio", "mesh_force_min_kn", "mesh_force_max_kn")


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _store_size(path: Path) -> dict[str, float]:
    files = [p for p in path.rglob("*") if p.is_file()]
    du = subprocess.run(["du", "-sk", str(path)], capture_output=True, text=True)
    return {"files": len(files), "bytes_mb": round(sum(p.stat().st_size for p in files) / 1e6,
                                                   2),
            "disk_mb": round(int(du.stdout.split()[0]) / 1024.0, 1) if du.returncode == 0
            else None}


def _rss_now_mb() -> float:
    """Resident memory of this process now (MB; Linux)."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def _noop(x):
    return x


def _write_costs(out: Path) -> dict[str, float]:
    """The client's store write per point: one record at a time and 256 at once."""
    from gearpair.sweep import Grid, SweepSettings
    from gearpair.sweep.point import run_point
    from gearpair.sweep.store import Store

    quick = SweepSettings(transient_periods=10, transient_time=0.0, kept_periods=10,
                          max_time=0.5, min_periods=4)
    g = Grid(("mu", "torque"), (tuple(0.01 + 1e-5 * k for k in range(1024)),
                                tuple(3900.0 for _ in range(1024))), "points")
    scratch = out / "write.zarr"
    if scratch.exists():
        shutil.rmtree(scratch)
    st = Store.open_or_create(scratch, g, quick)
    rec = run_point(0, g.names, (0.01, 3900.0), quick)
    recs = [{**rec, "index": i} for i in range(g.size)]
    t0 = time.perf_counter()
    for r in recs[:256]:
        st.write(r)
    one = (time.perf_counter() - t0) / 256
    t0 = time.perf_counter()
    for k in range(256, 1024, 256):
        st.write_many(recs[k:k + 256])
    batch = (time.perf_counter() - t0) / 768
    st.close()
    shutil.rmtree(scratch)
    return {"store_write_one_ms": round(1e3 * one, 2),
            "store_write_batch256_ms_per_point": round(1e3 * batch, 3)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("-n", type=int, default=1024, help="Sobol base sample (default 1024: "
                    "10,240 evaluations with second order over 4 parameters)")
    ap.add_argument("--dir", default="build/sa_scale", help="scratch folder (the store)")
    ap.add_argument("--noop-tasks", type=int, default=2000)
    ap.add_argument("--resume", action="store_true", help="keep an existing store (resume "
                    "it) instead of starting a new one")
    args = ap.parse_args(argv)

    from dask.distributed import Client

    from gearpair.sweep import SweepSettings, local_cluster, open_dataset, plot_indices
    from gearpair.sweep.sensitivity import run_sensitivity

    out = Path(args.dir)
    out.mkdir(parents=True, exist_ok=True)
    store = out / "sobol.zarr"
    if store.exists() and not args.resume:
        shutil.rmtree(store)
    res: dict = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                 "load_before": os.getloadavg(), "cores": os.cpu_count(),
                 "workers": args.workers, "ranges": RANGES, "n": args.n}
    t_all = time.perf_counter()
    with local_cluster(args.workers) as addr:
        client = Client(addr)
        res["cluster_start_s"] = round(time.perf_counter() - t_all, 2)
        res["client_rss_before_mb"] = round(_rss_now_mb(), 1)
        t0 = time.perf_counter()
        ds = run_sensitivity(RANGES, "sobol", args.n, OUTPUTS, SweepSettings(), store,
                             second_order=True, scheduler=addr, progress=True)
        wall = time.perf_counter() - t0
        peaks = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        res["load_after_study"] = os.getloadavg()
        t0 = time.perf_counter()
        futs = client.map(_noop, range(args.noop_tasks), pure=False)
        client.gather(futs)
        del futs
        res["noop_task_ms"] = round(1e3 * (time.perf_counter() - t0) / args.noop_tasks, 3)
        client.close()
    pts = open_dataset(store)
    run = pts.attrs["runs"][-1]
    cpu = pts["cpu_s"].values
    wall_pt = pts["wall_s"].values
    res["study"] = {
        "points": int(ds.attrs["points"]), "ok": run["ok"], "failed": run["failed"],
        "invalid": run["invalid"], "ran": run["ran"],
        "wall_s": round(wall, 1), "startup_s": run["startup_s"],
        "compute_s": run["elapsed_s"],
        "analysis_s": round(wall - run["elapsed_s"] - run["startup_s"], 1),
        "evaluations_per_min": round(60 * run["ran"] / wall, 1),
        "cpu_s_per_point_mean": round(float(cpu.mean()), 4),
        "cpu_s_per_point_median": round(float(sorted(cpu)[len(cpu) // 2]), 4),
        "cpu_s_per_point_max": round(float(cpu.max()), 3),
        "point_wall_s_sum": round(float(wall_pt.sum()), 1),
        "speedup_over_one_core": run["speedup_over_one_core"],
        "client_rss_before_mb": res["client_rss_before_mb"],
        "client_peak_rss_mb": round(_peak_rss_mb(), 1),
        "worker_peak_rss_mb": sorted(round(v, 1) for v in peaks.values()),
        "store": _store_size(store)}
    res.update(_write_costs(out))
    res["load_end"] = os.getloadavg()
    res["indices"] = {o: {k: ds[k].sel(output=o).values.round(4).tolist()
                          for k in ("S1", "S1_conf", "ST", "ST_conf")}
                      for o in OUTPUTS}
    res["indices"]["param"] = list(ds["param"].values)
    res["indices"]["S2_stick"] = ds["S2"].sel(output="stick_ratio").values.round(4).tolist()
    res["indices"]["S2_conf_stick"] = ds["S2_conf"].sel(output="stick_ratio").values.round(
        4).tolist()
    res["indices"]["constant_outputs"] = ds.attrs.get("constant_outputs")
    res["outputs_range"] = {o: [round(float(pts[o].min()), 4), round(float(pts[o].max()), 4)]
                            for o in OUTPUTS}
    plot_indices(ds, out / "sobol.png")
    (out / "sensitivity_scale.json").write_text(json.dumps(res, indent=1))
    s = res["study"]
    print(f"\n{res['date']}, {res['cores']} cores, {args.workers} workers, load before "
          f"{res['load_before'][0]:.1f}, after {res['load_after_study'][0]:.1f}")
    rows = [("evaluations (ok/failed/invalid)", f"{s['points']} ({s['ok']}/{s['failed']}/"
             f"{s['invalid']})"),
            ("wall time of the study (s)", s["wall_s"]),
            ("  start-up / points / indices (s)",
             f"{s['startup_s']} / {s['compute_s']} / {s['analysis_s']}"),
            ("evaluations per minute", s["evaluations_per_min"]),
            ("CPU per point: mean / median / max (s)",
             f"{s['cpu_s_per_point_mean']} / {s['cpu_s_per_point_median']} / "
             f"{s['cpu_s_per_point_max']}"),
            ("speed-up over one core", s["speedup_over_one_core"]),
            ("client RSS before / peak (MB; runs the scheduler)",
             f"{s['client_rss_before_mb']} / {s['client_peak_rss_mb']}"),
            ("worker peak RSS (MB)", ", ".join(map(str, s["worker_peak_rss_mb"]))),
            ("store: files, bytes (MB), on disk (MB)",
             f"{s['store']['files']}, {s['store']['bytes_mb']}, {s['store']['disk_mb']}"),
            ("dask no-op task round trip (ms)", res["noop_task_ms"]),
            ("store write per point: one / in a batch of 256 (ms)",
             f"{res['store_write_one_ms']} / {res['store_write_batch256_ms_per_point']}")]
    for k, v in rows:
        print(f"| {k} | {v} |")
    print(json.dumps(res["indices"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
