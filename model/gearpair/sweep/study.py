"""A parameter study: a `Grid` of points run into a `Store` as they finish, resumable.

`run_grid` checks every point and the store before any point runs, says how many points are
done and how many left, runs the missing ones (serially or on dask) and writes each record to
the store the moment it arrives, then adds the run's cost to the store.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .grid import Grid
from .progress import Progress
from .run import execute
from .settings import SweepSettings
from .store import Store


@dataclass
class StudyRun:
    """What one `run_grid` call did.

    Attributes
    ----------
    store : the store's path; grid : the points
    before : counts in the store before the run (`Store.counts`); after : after it
    ran : points run now; elapsed_s, startup_s, workers, scheduler, retried : the cost
    cpu_s : CPU time of the points run now (s), summed over workers
    interrupted : the run was stopped (Ctrl-C) before every point was in
    """

    store: Path
    grid: Grid
    before: dict[str, int]
    after: dict[str, int] = field(default_factory=dict)
    ran: int = 0
    elapsed_s: float = 0.0
    startup_s: float = 0.0
    workers: int = 1
    scheduler: str = "serial"
    retried: int = 0
    cpu_s: float = 0.0
    interrupted: bool = False

    def summary(self) -> dict[str, Any]:
        """Counts and cost: wall time, CPU time per point, the speed-up over one core (the
        CPU time of the points over the wall time of the computation)."""
        per = self.cpu_s / self.ran if self.ran else math.nan
        return {
            "store": str(self.store), "grid": self.grid.describe(), "points": self.grid.size,
            "done_before": self.grid.size - self.before.get("not_run", 0), "ran": self.ran,
            **{k: self.after.get(k, 0) for k in ("ok", "failed", "invalid", "not_run")},
            "retried": self.retried, "scheduler": self.scheduler, "workers": self.workers,
            "startup_s": round(self.startup_s, 3), "elapsed_s": round(self.elapsed_s, 3),
            "points_per_min": round(60 * self.ran / self.elapsed_s, 2)
            if self.elapsed_s > 0 else None,
            "cpu_s_per_point": round(per, 4) if self.ran else None,
            "speedup_over_one_core": round(self.cpu_s / self.elapsed_s, 2)
            if self.elapsed_s > 0 and self.ran else None,
            "interrupted": self.interrupted,
        }

    def report(self) -> str:
        """The end line: counts, wall time, CPU time per point, speed-up over one core."""
        s = self.summary()
        head = "interrupted" if self.interrupted else "sweep"
        if not self.ran and not self.interrupted:
            return (f"sweep: {s['grid']}: nothing to run ({s['ok']} ok, {s['failed']} failed, "
                    f"{s['invalid']} invalid in the store {self.store})")
        line = (f"{head}: {s['grid']}: ran {s['ran']} now ({s['ok']} ok, {s['failed']} "
                f"failed, {s['invalid']} invalid, {s['not_run']} not run in all) in "
                f"{s['elapsed_s']:.1f} s on {self.workers} worker(s) [{self.scheduler}], "
                f"startup {s['startup_s']:.1f} s")
        if self.ran:
            line += (f"; {s['points_per_min']} points/min, CPU {s['cpu_s_per_point']:.3f} s "
                     f"per point, speed-up over one core {s['speedup_over_one_core']}")
        if self.interrupted:
            line += f"\nthe finished points are in {self.store}; the same command resumes"
        return line


def check_grid(grid: Grid, settings: SweepSettings) -> None:
    """``ValueError`` naming the parameter and its range for the first point outside it
    (before any point runs). A point outside the model's validity (a negative torque
    without backlash) is not refused here: it becomes an ``invalid`` record."""
    if grid.kind == "product":  # each axis alone: the ranges are per parameter
        base = {n: v[0] for n, v in zip(grid.names, grid.values, strict=True)}
        for n, vals in zip(grid.names, grid.values, strict=True):
            for v in vals:
                settings.check_point({**base, n: v})
        return
    for i, point in grid.points():
        try:
            settings.check_point(point)
        except ValueError as exc:
            raise ValueError(f"point {i} (line {i + 2} of the list): {exc}") from None


def run_grid(grid: Grid, settings: SweepSettings | None = None,
             store: str | Path | Store = "sweep.zarr",
             *, scheduler: str | None = None, workers: int | None = None, retries: int = 1,
             rerun_failed: bool = False, new_store: bool = False, progress: bool = True,
             stream=None, on_record=None) -> StudyRun:
    """Run the points of ``grid`` not yet in ``store`` and store each one as it finishes.

    Parameters
    ----------
    grid : the points (`Grid.parse`, `Grid.product`, `Grid.from_csv`)
    settings : held inputs, effects and durations (`SweepSettings`)
    store : path of the Zarr store: created if missing; resumed if it holds this sweep
        (same grid, settings and engine version), else refused (``ValueError`` naming the
        difference) unless ``new_store`` (the old store is then replaced); or a `Store`
        already opened with `Store.open_or_create`
    scheduler, workers, retries : as in `run_sweep`
    rerun_failed : run the points stored as failed or invalid again (default: kept)
    progress : progress bar and messages on ``stream`` (stderr)
    on_record : called with each record after it is stored (tests, custom progress)

    Every point is checked (`check_grid`) and the store opened before any point runs.
    Read the results with `gearpair.sweep.open_dataset(store)`.
    """
    settings = settings or SweepSettings()
    if retries < 0:
        raise ValueError(f"retries = {retries!r} must be >= 0")
    check_grid(grid, settings)
    if isinstance(store, Store):  # opened and checked by the caller, who closes it
        st, own = store, False
        if st.differences(grid, settings):
            raise ValueError(f"store {st.path} holds another sweep")
    else:
        st, own = Store.open_or_create(store, grid, settings, new=new_store), True
    try:
        return _run_into(st, grid, settings, scheduler=scheduler, workers=workers,
                         retries=retries, rerun_failed=rerun_failed, progress=progress,
                         stream=stream, on_record=on_record)
    finally:
        if own:
            st.close()


def _run_into(st: Store, grid: Grid, settings: SweepSettings, *, scheduler, workers, retries,
              rerun_failed, progress, stream, on_record) -> StudyRun:
    store = st.path
    out = sys.stderr if stream is None else stream
    before = st.counts()
    todo = st.todo(rerun_failed)
    run = StudyRun(Path(store), grid, before)
    if progress:
        done = grid.size - before["not_run"]
        kept = done - (len(todo) - before["not_run"])
        print(f"store {store}: {grid.describe()}; {done} done ({before['ok']} ok, "
              f"{before['failed']} failed, {before['invalid']} invalid), {len(todo)} to run"
              + (f", {kept} kept" if rerun_failed else "")
              + ("" if rerun_failed or not (before["failed"] + before["invalid"])
                 else " (failed and invalid points are kept; --rerun-failed runs them)"),
              file=out, flush=True)
    if todo:
        names = grid.names if len(grid.names) > 1 else grid.names[0]
        tasks = []
        for i in todo:
            p = grid.point(i)
            tasks.append((i, names, tuple(p.values()) if len(p) > 1 else p[names]))
        bar = Progress(len(todo), "sweep", stream, progress)

        def sink(recs: list[dict]) -> None:
            st.write_many(recs)
            for rec in recs:
                run.ran += 1
                run.cpu_s += float(rec.get("cpu_s", 0.0) or 0.0)
                if on_record is not None:
                    on_record(rec)

        t0 = time.perf_counter()
        try:
            cost = execute(tasks, settings, sink, scheduler=scheduler, workers=workers,
                           retries=retries, bar=bar)
            run.elapsed_s, run.startup_s = cost.elapsed_s, cost.startup_s
            run.workers, run.scheduler, run.retried = cost.workers, cost.scheduler, cost.retried
        except KeyboardInterrupt:
            run.interrupted = True
            run.elapsed_s = time.perf_counter() - t0
            if progress:
                print(file=out)
    run.after = st.counts()
    st.add_run({"finished": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                **{k: v for k, v in run.summary().items() if k not in ("store", "grid")}})
    return run
