"""The whole measurement: every section in order, one JSON-ready dict."""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

from .chost import host_measurements
from .effect_cost import cost_table
from .fmu import build_fmus, fmu_measurements, fmu_startup
from .memory import memory_peak
from .plain import plain_rows
from .runs import _record, machine_info, regime_effects
from .settings import DEFAULT, LADDER, REGIMES, Progress, Settings, _quiet
from .targets import targets
from .work_precision import _step_rtols, core_step_costs, engine_rows, equal_accuracy, references


def warm_up(progress: Progress = _quiet) -> float:
    """Load (or compile, about 30 s the first time) the fast engine's kernels."""
    from .. import make_engine
    from ..effects import Effects

    t0 = time.perf_counter()
    for fx in [regime_effects(r) for r in REGIMES] + [Effects(**kw) for _, kw in LADDER]:
        _record(make_engine(None, fx, "fast"), 0.002, 1e-3)
    wall = time.perf_counter() - t0
    progress(f"fast engine warm-up: {wall:.1f} s")
    return wall




def run(s: Settings = DEFAULT, progress: Progress = _quiet, fmu_dir: str | Path | None = None
        ) -> dict:
    """Run every section of the benchmark with settings ``s``; a JSON-ready dict.

    ``fmu_dir``: where to build the FMUs (default a temporary folder).
    """
    t_start = time.perf_counter()
    result: dict = {"machine": machine_info(), "settings": asdict(s)}
    result["warm_up_s"] = warm_up(progress)
    refs, checks = references(s, progress)
    result["reference"] = {
        "engine": "fast", "rtol": s.ref_rtol, "horizon_s": float(refs[REGIMES[0]]["time"][-1]),
        "dt": s.dt, "cross_check": checks}
    rows = engine_rows(s, refs, progress)
    plain, plain_checks, note = plain_rows(s, refs, progress)
    rows.extend(plain)
    checks.extend(plain_checks)
    result["plain_scipy"] = {"script": "benchmarks/plain_scipy.py", "note": note}
    core = core_step_costs(s, _step_rtols(rows, s.fmu_rtols))
    progress("fast core at 1e-3 s steps: done")
    result.update(work_precision=rows, core_steps=core, fmu=None, startup=None,
                  c_host=None)
    if s.fmu:
        with tempfile.TemporaryDirectory(prefix="gearpair_bench_fmu_") as tmp:
            try:  # a failing FMU section is reported, the other sections still run
                fmu, noop = build_fmus(fmu_dir or tmp)
                fm = fmu_measurements(s, refs, fmu, noop, progress)
                result["fmu"] = {"steps": fm["steps"], "calls": fm["calls"]}
                rows.extend(fm["rows"])
                result["c_host"] = host_measurements(s, fmu, noop, Path(tmp) / "host",
                                                     progress)
                if s.startup:
                    result["startup"] = fmu_startup(fmu, progress)
            except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
                result["fmu_error"] = f"{type(exc).__name__}: {exc}"
                progress(f"FMU section failed: {result['fmu_error']}")
    result["equal_accuracy"] = equal_accuracy(rows)
    result["cost"] = cost_table(s, progress=progress)
    result["memory"] = memory_peak(s.memory_t_end) if s.memory else None
    if s.memory:
        progress(f"memory: peak {result['memory']['peak_rss_mb']:.0f} MB")
    result["targets"] = targets(result)
    result["machine"]["load_average_end"] = [round(x, 2) for x in os.getloadavg()] \
        if hasattr(os, "getloadavg") else None
    result["wall_s"] = time.perf_counter() - t_start
    return result

