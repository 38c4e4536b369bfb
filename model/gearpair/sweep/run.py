"""Running the points: serially in this process or on dask.distributed (a local cluster or
a running scheduler), with retries of failed points."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass

from ..params import RTOL_MIN
from .point import _blank, _warm, run_point
from .progress import Progress
from .result import SweepResult
from .settings import SweepSettings, sweepable

BATCH = 256  # most records handed to the sink at once
# A serial run hands each record to the sink at once (0), or the records finished within
# this many seconds together (a function in place of the model, `sensitivity.model_hook`,
# finishes points in microseconds, and a store write per point would cost far more)
SERIAL_FLUSH_S = 0.0


@dataclass
class Cost:
    """What a run of points cost.

    Attributes
    ----------
    elapsed_s : wall time of the computation (submission to last result), s
    startup_s : wall time to start or reach the cluster and warm the compiled code, s
    workers : worker threads used; scheduler : ``local``, ``serial`` or an address
    retried : reruns of failed points
    """

    elapsed_s: float = 0.0
    startup_s: float = 0.0
    workers: int = 1
    scheduler: str = "serial"
    retried: int = 0


def run_sweep(name: str, values, settings: SweepSettings | None = None, *,
              scheduler: str | None = None, workers: int | None = None, retries: int = 1,
              progress: bool = True, stream=None) -> SweepResult:
    """Run ``run_point`` for every value of ``name`` and gather the records.

    Parameters
    ----------
    name : parameter to sweep (`sweepable`): ``speed_rpm`` (r/min), ``torque`` (N.m) or a
        `GearParams` field (SI, e.g. ``mu``)
    values : the values (any order; the output keeps it)
    settings : held inputs, effects and durations
    scheduler : None for a new local cluster of ``workers`` processes; ``"serial"`` to run in
        this process (no dask); otherwise the address of a running dask.distributed scheduler
        (e.g. ``tcp://10.0.0.5:8786``)
    workers : local worker processes (default: the CPU count)
    retries : how many times a failed point is run again (each with ``rtol / 10``)
    progress : draw a progress bar on ``stream`` (stderr by default)

    A value the parameter's range refuses is an ``invalid`` record here (not an error):
    `gearpair.sweep.grids.run_grid` refuses it before any point runs.
    """
    settings = settings or SweepSettings()
    if name not in sweepable():
        raise ValueError(f"cannot sweep {name!r}; choose one of " + ", ".join(sweepable()))
    values = [float(v) for v in values]
    if not values:
        raise ValueError("no values to sweep")
    if retries < 0:
        raise ValueError(f"retries = {retries!r} must be >= 0")
    bar = Progress(len(values), f"sweep {name}", stream, progress)
    records: dict[int, dict] = {}
    cost = execute([(i, name, v) for i, v in enumerate(values)], settings,
                   lambda recs: records.update((r["index"], r) for r in recs),
                   scheduler=scheduler, workers=workers, retries=retries, bar=bar)
    recs = [records[i] for i in range(len(values))]
    return SweepResult(name, values, settings, recs, cost.elapsed_s, cost.startup_s,
                       cost.workers, cost.scheduler, cost.retried)


def execute(tasks: list[tuple], settings: SweepSettings, sink: Callable[[list[dict]], None], *,
            scheduler: str | None = None, workers: int | None = None, retries: int = 1,
            bar: Progress | None = None) -> Cost:
    """Run the points ``tasks`` (``(index, name, value)`` as `run_point` takes them) and hand
    the final records (a failed point's after its retries) to ``sink`` as soon as they are
    in: a list of one, or of every result waiting at that moment (at most `BATCH`), so that
    a store writes a burst of results at once.

    ``scheduler``: ``"serial"`` (this process), None (a new local cluster of ``workers``
    processes) or a scheduler's address. Returns the `Cost`.
    """
    bar = bar or Progress(len(tasks), "sweep", enabled=False)
    t0 = time.perf_counter()
    if scheduler == "serial":
        _warm()
        startup = time.perf_counter() - t0
        t1 = time.perf_counter()
        bar.start()
        retried = 0
        pending: list[dict] = []
        last = time.perf_counter()

        def flush() -> None:
            nonlocal pending, last
            out, pending, last = pending, [], time.perf_counter()
            if out:
                sink(out)
                for r in out:
                    bar.update(r["status"] != "failed")

        try:
            for i, name, v in tasks:
                rec = run_point(i, name, v, settings)
                for a in range(2, retries + 2):
                    if rec["status"] != "failed":  # ok, or invalid: a tighter rtol cannot help
                        break
                    bar.update(False, retrying=True)
                    retried += 1
                    rec = run_point(i, name, v, settings, _tighter(settings.rtol, a), a)
                pending.append(rec)
                if len(pending) >= BATCH or time.perf_counter() - last >= SERIAL_FLUSH_S:
                    flush()
        finally:  # the finished points are stored also when the run is stopped
            flush()
        return Cost(time.perf_counter() - t1, startup, 1, "serial", retried)
    return _run_dask(tasks, settings, sink, scheduler, workers, retries, bar, t0)


def _tighter(rtol: float, attempt: int) -> float:
    return max(rtol / 10.0 ** (attempt - 1), RTOL_MIN)


def _local_cluster(workers: int | None):
    import logging

    try:
        from dask.distributed import LocalCluster
    except ImportError as exc:  # pragma: no cover - the extra is missing
        raise ImportError("sweeps need dask.distributed: pip install 'gearpair[sweep]'") from exc
    _warm()  # compile once here, before the workers start
    n = int(workers or os.cpu_count() or 1)
    # No dashboard; the scheduler's HTTP server (health checks) on a free port, so that a
    # second cluster on the machine does not warn about port 8787.
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                        dashboard_address=None, silence_logs=logging.ERROR,
                        scheduler_kwargs={"dashboard_address": ":0"})


@contextmanager
def local_cluster(workers: int | None = None):
    """A local cluster of ``workers`` single-threaded processes for several sweeps; yields
    its scheduler address (pass it as ``scheduler``). Call it under
    ``if __name__ == "__main__":`` in scripts (worker processes are spawned)."""
    cluster = _local_cluster(workers)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


def _run_dask(tasks, settings, sink, scheduler, workers, retries, bar, t0) -> Cost:
    from dask.distributed import Client, as_completed

    cluster = None
    if scheduler:
        client = Client(scheduler)
        label = scheduler
    else:
        cluster = _local_cluster(workers)
        client = Client(cluster)
        label = "local"
    try:
        client.wait_for_workers(1, timeout=120)
        info = client.scheduler_info(n_workers=-1) if _accepts_n_workers(client) \
            else client.scheduler_info()
        nthreads = sum(int(w.get("nthreads", 1)) for w in info["workers"].values()) or 1
        # Load the compiled kernels on every worker before the clock starts.
        client.run(_warm)
        startup = time.perf_counter() - t0
        t1 = time.perf_counter()
        bar.start()
        futs, first = {}, []
        for i, name, v in tasks:
            f = client.submit(run_point, i, name, v, settings, None, 1, pure=False)
            futs[f.key] = (i, name, v, 1)
            first.append(f)
        ac = as_completed(first)
        del first
        retried = 0
        ready: list[dict] = []
        # A worker that dies takes its running tasks with it; the scheduler runs them again
        # on another worker (each result still arrives here once, its future's).
        for fut in ac:
            i, name, v, attempt = futs.pop(fut.key)
            try:
                rec = fut.result()
            except Exception as exc:  # noqa: BLE001 - a task that killed its workers
                rec = _blank(i, name, v, settings)
                rec["attempts"] = attempt
                rec["error"] = f"{type(exc).__name__}: {exc}"
            fut.release()
            if rec["status"] == "failed" and attempt <= retries:
                retried += 1
                bar.update(False, retrying=True)
                g = client.submit(run_point, i, name, v, settings,
                                  _tighter(settings.rtol, attempt + 1), attempt + 1, pure=False)
                futs[g.key] = (i, name, v, attempt + 1)
                ac.add(g)
                continue
            ready.append(rec)
            if len(ready) >= BATCH or not ac.has_ready():
                sink(ready)
                for r in ready:
                    bar.update(r["status"] != "failed")
                ready = []
        elapsed = time.perf_counter() - t1
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return Cost(elapsed, startup, nthreads, label, retried)


def _accepts_n_workers(client) -> bool:
    import inspect

    return "n_workers" in inspect.signature(client.scheduler_info).parameters


