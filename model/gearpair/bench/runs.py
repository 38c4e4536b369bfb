"""Running an engine, timing it on two clocks, and its error against a reference.

Also the description of the machine a run happened on."""

from __future__ import annotations

import contextlib
import datetime
import math
import os
import platform
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .settings import FRICTION_OF, STIFFNESS_OF

PACKAGE = Path(__file__).resolve().parents[1]  # this gearpair package


# -- machine ------------------------------------------------------------------------------------
def _version(dist: str) -> str | None:
    try:
        from importlib.metadata import version

        return version(dist)
    except Exception:  # noqa: BLE001 - not installed
        return None


def machine_info() -> dict:
    """CPU model, core count, memory, load, package versions, commit and date of this run."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem_gb = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                mem_gb = round(int(line.split()[1]) / 2**20, 1)
    except (OSError, ValueError):
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    commit = _commit()
    return {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "cpu": cpu, "cores": os.cpu_count(), "usable_cores": usable, "memory_gb": mem_gb,
        "load_average": [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg")
        else None,
        "os": platform.platform(), "python": platform.python_version(),
        "numpy": np.__version__, "scipy": _version("scipy"), "numba": _version("numba"),
        "fmpy": _version("fmpy"), "pythonfmu": _version("pythonfmu"),
        "gearpair": _version("gearpair"), "commit": commit,
    }


def _commit() -> str | None:
    """The git commit of the work tree that holds this package's files (a checkout), with
    `` + uncommitted changes`` when they differ from it; None for an installed package."""
    def git(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(["git", "-C", str(PACKAGE), *args], capture_output=True,
                              text=True, timeout=10)

    try:
        if git("ls-files", "--error-unmatch", "__init__.py").returncode != 0:
            return None  # not a file of a work tree (an installed package)
        rev = git("rev-parse", "--short", "HEAD")
        if rev.returncode != 0:
            return None
        dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip()
        return rev.stdout.strip() + (" + uncommitted changes" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


# -- runs and errors ------------------------------------------------------------------------------
def regime_effects(regime: str):
    """The `Effects` of a regime: Table 1 gear pair, separation, 6-DOF; potential-energy
    stiffness with friction off, ``nominal`` (sliding) or ``stick_slip``, or rectangular
    stiffness with ``stick_slip`` (`settings.RECTANGULAR`)."""
    from ..effects import Effects

    return Effects(friction=FRICTION_OF[regime], stiffness=STIFFNESS_OF[regime])


class Timing(NamedTuple):
    """A duration (s) as wall time and as CPU time of this process (``time.process_time``).

    On a shared machine the CPU time is the steadier of the two: it leaves out the time the
    process waited for a core.
    """

    wall: float
    cpu: float

    def __sub__(self, other: Timing) -> Timing:
        return Timing(self.wall - other.wall, self.cpu - other.cpu)

    def best(self, other: Timing) -> Timing:
        """Each clock's smaller value (best of repeated runs)."""
        return Timing(min(self.wall, other.wall), min(self.cpu, other.cpu))


NEVER = Timing(math.inf, math.inf)


def clock() -> Timing:
    """Now, on both clocks (subtract two readings for a `Timing`)."""
    return Timing(time.perf_counter(), time.process_time())


def _record(engine, t_end: float, dt: float) -> tuple[Timing, dict]:
    """Step an engine from the static start at the default point, recording every ``dt``
    (`gearpair.results.simulate`); (time taken, signals)."""
    from ..results import simulate

    t0 = clock()
    traj = simulate(engine=engine, t_end=t_end, dt=dt)
    took = clock() - t0
    sig = {k: np.asarray(traj[k], dtype=float) for k in ("time", "dte", "mesh_force")}
    return took, sig


def _record_calls(engine, t_end: float, dt: float) -> Timing:
    """The loop an FMU master drives: one `advance` + `outputs` call per step of ``dt``, from
    the static start at the default point."""
    from ..results import OperatingPoint

    op = OperatingPoint()
    n = int(round(t_end / dt))
    engine.reset(0.0, op.torque, op.speed)
    t0 = clock()
    for i in range(1, n + 1):
        engine.advance(i * dt, op.torque, op.speed)
        engine.outputs()
    return clock() - t0


def engine_run(regime: str, engine: str, t_end: float, dt: float, repeats: int = 1,
               **options) -> tuple[Timing, dict]:
    """Best time over ``repeats`` runs of an engine and the signals of the last.

    The engine is built outside the timed part (its construction, a few ms to 20 ms, is a
    one-off cost); the timed part is `gearpair.results.simulate` stepping and recording.
    """
    from .. import make_engine

    best, sig = NEVER, {}
    for _ in range(max(1, repeats)):
        eng = make_engine(None, regime_effects(regime), engine, **options)
        took, sig = _record(eng, t_end, dt)
        best = best.best(took)
    return best, sig


def relative_error(t: np.ndarray, x: np.ndarray, ref: dict, name: str,
                   t_max: float | None = None) -> float:
    """max |x - x_ref| / max |x_ref| over the samples of ``t`` on the reference grid up to
    ``t_max`` (samples between grid points are skipped)."""
    dt = ref["dt"]
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    t_max = float(t[-1]) if t_max is None else t_max
    idx = np.rint(t / dt).astype(np.int64)
    ok = (np.abs(t - idx * dt) <= 1e-6 * dt) & (idx < len(ref["time"])) \
        & (t <= t_max + 1e-6 * dt)
    if not np.any(ok):
        raise ValueError("no common samples with the reference")
    scale = float(np.max(np.abs(ref[name][ref["time"] <= t_max + 1e-6 * dt])))
    return float(np.max(np.abs(x[ok] - ref[name][idx[ok]])) / scale)


def _errors(sig: dict, ref: dict, window: float) -> dict:
    return {
        "err_dte": relative_error(sig["time"], sig["dte"], ref, "dte", window),
        "err_force": relative_error(sig["time"], sig["mesh_force"], ref, "mesh_force", window),
        "err_dte_horizon": relative_error(sig["time"], sig["dte"], ref, "dte"),
        "err_force_horizon": relative_error(sig["time"], sig["mesh_force"], ref, "mesh_force"),
    }



class BudgetExceeded(RuntimeError):
    """A benchmark run took longer than its budget."""


@contextlib.contextmanager
def time_limit(seconds: float | None):
    """Raise `BudgetExceeded` in the block after ``seconds`` of wall time (POSIX main thread
    only; elsewhere no limit)."""
    usable = seconds and hasattr(signal, "setitimer") \
        and threading.current_thread() is threading.main_thread()
    if not usable:
        yield
        return

    def alarm(signum, frame):
        raise BudgetExceeded(f"stopped after the run budget of {seconds:g} s of wall time")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)



def _best_of(fn: Callable[[], Timing], repeats: int) -> tuple[Timing | None, str | None]:
    """Best of ``repeats`` calls of ``fn`` (a `Timing`), or (None, message) on failure."""
    best = NEVER
    try:
        for _ in range(max(1, repeats)):
            best = best.best(fn())
    except (RuntimeError, ArithmeticError, ValueError) as exc:
        return None, f"{type(exc).__name__}: {exc}"
    return best, None

