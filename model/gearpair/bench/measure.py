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
from .fmi3 import fmi3_measurements, wine_measurements
from .fmu import build_noop, fmu_measurements, fmu_startup
from .memory import memory_peak
from .plain import plain_rows
from .runs import _record, _record_calls, machine_info, regime_effects
from .settings import DEFAULT, LADDER, REGIMES, WP_REGIMES, Progress, Settings, _quiet
from .targets import targets
from .work_precision import _step_rtols, core_step_costs, engine_rows, equal_accuracy, references

# the import name of the package the FMU bundles (fmu_src/GearPair.py's BUNDLE): numba's
# compiled code names its module, so the FMU's engine is compiled under this name
FMU_BUNDLE = "_gearpair_fmu"


def warm_up(progress: Progress = _quiet) -> float:
    """Load (or compile, once per engine change) every compiled path of the fast engine
    that the benchmark times: the grid recorder and the per-step ``advance`` of each regime
    (the rectangular one included) and ladder rung (the exact propagator included), so no
    timed run compiles."""
    from .. import jitcache, make_engine
    from ..effects import Effects

    before = jitcache.STATS["compiled"]
    t0 = time.perf_counter()
    for fx in [regime_effects(r) for r in WP_REGIMES] + [Effects(**kw) for _, kw in LADDER]:
        _record(make_engine(None, fx, "fast"), 0.002, 1e-3)
        _record_calls(make_engine(None, fx, "fast"), 0.002, 1e-3)
    wall = time.perf_counter() - t0
    if jitcache.STATS["compiled"] > before:
        progress(f"fast engine warm-up: compiled once in {wall:.1f} s (later runs load it "
                 f"from {jitcache.CACHE_PATH})")
    else:
        progress(f"fast engine warm-up: {wall:.1f} s")
    return wall


class _FmuEngineCompile:
    """The engine that GearPair.fmu ships, compiled for a portable CPU in a child process
    (`gearpair.shipped.ship`, on a copy of the package) while this process warms its own
    engine: on a first run after an engine change the two compiles take about 30 s each,
    and on two cores they overlap. The rebuild of a stale FMU (`find_fmu`) then finds its
    engine in the cache."""

    def __init__(self, progress: Progress):
        import threading

        self.progress, self.error, self.manifest = progress, None, None
        self.t0 = time.perf_counter()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        import shutil

        from .. import shipped

        try:
            with tempfile.TemporaryDirectory(prefix="gearpair_bench_ship_") as tmp:
                pkg = Path(tmp) / "gearpair"
                shutil.copytree(Path(__file__).resolve().parents[1], pkg,
                                ignore=shutil.ignore_patterns("__pycache__", "*.pyc",
                                                              shipped.SHIPPED_FOLDER))
                self.manifest = shipped.ship(pkg, FMU_BUNDLE)
        except Exception as exc:  # noqa: BLE001 - the rebuild compiles (and reports) it again
            self.error = f"{type(exc).__name__}: {exc}"

    def wait(self) -> None:
        """Block until the compile is done (before any timed section) and say how it went."""
        if self.thread.is_alive():
            self.progress("waiting for the FMU's engine (seconds from the cache, about 30 s "
                          "when it compiles, once per engine change)")
        self.thread.join()
        took = time.perf_counter() - self.t0
        if self.error:
            self.progress(f"FMU's engine: compiling it ahead failed ({self.error}); the FMU "
                          "build retries")
        elif self.manifest is not None:
            how = "compiled once" if self.manifest["compiled"]["source"] == "compiled" \
                else "loaded from the cache"
            self.progress(f"FMU's engine (for {self.manifest['cpu_name']} CPUs): {how}, done "
                          f"after {took:.1f} s")


def run(s: Settings = DEFAULT, progress: Progress = _quiet, fmu: str | Path | None = None,
        fmu_dir: str | Path | None = None) -> dict:
    """Run every section of the benchmark with settings ``s``; a JSON-ready dict.

    ``fmu``: the GearPair FMU to measure (`gearpair.scenes.location.find_fmu`: default
    ``$GEARPAIR_FMU``, else ``dist/GearPair.fmu`` of the current directory, rebuilt there
    when stale); ``fmu_dir``: where to build the no-op slave (default a temporary folder).

    Raises
    ------
    SceneError
        ``s.fmu`` and no FMU there (before anything runs), with how to build or pass one.
    """
    from ..scenes.location import locate_fmu

    t_start = time.perf_counter()
    result: dict = {"machine": machine_info(), "settings": asdict(s)}
    ahead = None
    if s.fmu:
        _, rebuild = locate_fmu(fmu)
        if rebuild:  # find_fmu rebuilds it: its engine compiles here, beside the warm-up
            progress(f"the FMU is stale ({rebuild}) and is rebuilt: compiling its engine in "
                     "a child process (about 30 s once per engine change; seconds when "
                     "cached) beside this process's warm-up")
            ahead = _FmuEngineCompile(progress)
    result["warm_up_s"] = warm_up(progress)
    if ahead is not None:  # nothing timed runs while a compile takes a core
        ahead.wait()
    refs, checks = references(s, progress)
    result["reference"] = {
        "engine": "fast", "rtol": s.ref_rtol, "horizon_s": float(refs[REGIMES[0]]["time"][-1]),
        "dt": s.dt, "cross_check": checks}
    rows = engine_rows(s, refs, progress)
    # the plain rows' rounds time the fast core's rows again: both best of s.repeats runs
    # spread over the same minutes
    plain, plain_checks = plain_rows(s, refs, progress, fast_rows=rows)
    rows.extend(plain)
    checks.extend(plain_checks)
    result["plain_scipy"] = {"module": "gearpair.bench.plain_scipy"}
    core = core_step_costs(s, _step_rtols(rows, s.fmu_rtols))
    progress("fast core at 1e-3 s steps: done")
    result.update(work_precision=rows, core_steps=core, fmu=None, startup=None,
                  c_host=None, fmi3_host=None, wine_host=None)
    if s.fmu:
        from ..scenes.location import find_fmu

        with tempfile.TemporaryDirectory(prefix="gearpair_bench_fmu_") as tmp:
            try:  # a failing FMU section is reported, the other sections still run
                gearpair_fmu = find_fmu(fmu)
                progress(f"FMU: {gearpair_fmu}; building the no-op slave on its binary")
                noop = build_noop(gearpair_fmu, fmu_dir or tmp)
                result["fmu_file"] = str(gearpair_fmu)
                fm = fmu_measurements(s, refs, gearpair_fmu, noop, progress)
                result["fmu"] = {"steps": fm["steps"], "calls": fm["calls"]}
                rows.extend(fm["rows"])
                result["c_host"] = host_measurements(s, gearpair_fmu, noop,
                                                     Path(tmp) / "host", progress)
                result["fmi3_host"] = fmi3_measurements(s, gearpair_fmu, Path(tmp) / "fmi3",
                                                        progress)
                result["wine_host"] = wine_measurements(s, gearpair_fmu, Path(tmp) / "wine",
                                                        progress)
                if s.startup:
                    result["startup"] = fmu_startup(gearpair_fmu, progress,
                                                    compile_row=s.name != "quick")
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

