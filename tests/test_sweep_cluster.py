"""A lost worker loses nothing: a real dask.distributed cluster started the way a
user starts one (`dask scheduler`, two `dask worker` processes), one worker killed mid-sweep;
every point completes exactly once and the store equals an uninterrupted run bit for bit."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gearpair.sweep import Grid, SweepSettings, open_dataset, run_grid
from gearpair.sweep.store import NUMERIC

pytest.importorskip("distributed")
pytest.importorskip("xarray")

# points of about 0.1-0.3 s of CPU each: long enough that the kill lands inside a task
SETTINGS = SweepSettings(transient_periods=60, transient_time=0.0, kept_periods=60,
                         max_time=2.0, min_periods=4)
PHYSICS = [n for n in NUMERIC if n not in ("wall_s", "cpu_s")]


def _dask(*args: str) -> list[str]:
    """The `dask` command next to this interpreter (as a user runs it), else its module."""
    exe = Path(sys.executable).with_name("dask")
    if exe.exists():
        return [str(exe), *args]
    mod = {"scheduler": "distributed.cli.dask_scheduler",
           "worker": "distributed.cli.dask_worker"}[args[0]]
    return [sys.executable, "-m", mod, *args[1:]]


def _wait(pred, timeout: float, what: str) -> None:
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout:
            raise TimeoutError(what)
        time.sleep(0.1)


@pytest.mark.slow
def test_killed_worker_loses_no_point(tmp_path):
    sched_file = tmp_path / "scheduler.json"
    log = (tmp_path / "dask.log").open("w")
    procs: list[subprocess.Popen] = []
    try:
        procs.append(subprocess.Popen(
            _dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                  "--scheduler-file", str(sched_file)), stdout=log, stderr=log))
        _wait(sched_file.exists, 60, "the scheduler did not start")
        addr = json.loads(sched_file.read_text())["address"]
        workers = {}
        for name in ("w1", "w2"):  # no nanny: killing the process loses the worker for good
            p = subprocess.Popen(_dask("worker", "--scheduler-file", str(sched_file),
                                       "--nthreads", "1", "--no-nanny", "--no-dashboard",
                                       "--name", name, "--host", "127.0.0.1"),
                                 stdout=log, stderr=log)
            procs.append(p)
            workers[p.pid] = p
        from dask.distributed import Client

        watch = Client(addr)  # the test's own view of the scheduler
        watch.wait_for_workers(2, timeout=60)
        pids = watch.run(os.getpid)  # {worker address: its process id}
        grid = Grid.parse(["speed_rpm=100,140,180,220", "mu=0.01,0.02,0.03,0.04"])
        seen: list[int] = []
        killed: list[int] = []
        lost: list = []

        def kill_one_worker(rec: dict) -> None:
            seen.append(rec["index"])
            if len(seen) == 3:  # both workers are busy with later points now
                pid = int(rec["worker"].rpartition(":")[2])
                where = next(a for a, w in pids.items() if w == pid)
                lost.extend(watch.processing()[where])  # its tasks go down with it
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)

        run = run_grid(grid, SETTINGS, tmp_path / "c.zarr", scheduler=addr, retries=0,
                       progress=False, on_record=kill_one_worker)
        watch.close()
        assert killed and workers[killed[0]].wait(timeout=30) == -signal.SIGKILL
        assert lost  # the kill took at least one unfinished point with it
        assert sorted(seen) == list(range(16))  # every point once, none twice
        assert run.after == {"ok": 16, "failed": 0, "invalid": 0, "not_run": 0}
        ds = open_dataset(tmp_path / "c.zarr").load()
        hosts = {str(w).rpartition(":")[2] for w in ds["worker"].values.ravel()}
        assert str(killed[0]) in hosts and len(hosts) == 2  # both worked; one is gone
        assert (ds["attempts"] == 1).all()  # dask moved the lost tasks, no retry of ours
        # an uninterrupted run gives the same numbers, bit for bit
        run_grid(grid, SETTINGS, tmp_path / "s.zarr", scheduler="serial", progress=False)
        whole = open_dataset(tmp_path / "s.zarr").load()
        for name in PHYSICS:
            if name in ds:
                np.testing.assert_array_equal(ds[name].values, whole[name].values,
                                              err_msg=name)
        np.testing.assert_array_equal(ds["poincare"].values, whole["poincare"].values)
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        log.close()
