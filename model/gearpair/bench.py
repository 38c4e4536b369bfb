"""Benchmark: work-precision of the integrators, cost of the FMU and cost of each effect.

``gearpair bench [--quick | --full] [--json] [--plot FILE] [--memory]`` (issues #4 and #5)
measures in one run, side by side on the same machine:

- **work-precision** for three regimes at the paper's low-speed point (3900 N.m, 100 r/min):
  no friction, sliding (Coulomb friction in the nominal direction, no stick) and stick-slip.
  Every method starts from the static equilibrium at t = 0 and records DTE and mesh force on
  the same output grid; the error is the largest deviation from a tight reference divided by
  the reference's largest magnitude, the cost the wall time (and the CPU time) per simulated
  second. Methods: the fast core (`gearpair.fast.FastEngine`) at several tolerances, with its
  default DOP853 and with Dormand-Prince 5(4) (rows ``fast dp5``); scipy's
  RK45, DOP853, Radau and LSODA, run as `gearpair.reference.ReferenceEngine` (scipy's
  ``OdeSolver`` classes, which ``solve_ivp`` drives, stepped segment by segment over the same
  physics); the FMU through fmpy at communication steps 1e-5, 1e-4 and 1e-3 s.
- **equal accuracy**: per method the cheapest setting with DTE error <= 1e-6, and the ratio
  fastest scipy method / fast core.
- **FMU cost** at a 1e-3 s step against the core at the same step (driven as the FMU drives
  it: one ``advance`` + ``outputs`` call per step) and the plumbing floor (the
  same fmpy call on a pythonfmu slave that does nothing, ``examples/bench_noop``); the cost of
  one set+doStep+get call; the first instantiation with an empty numba cache (compile)
  against a warm one.
- **cost of effects** (issue #5): wall time per simulated second of every shipped scene and
  of the effect ladder torsional constant stiffness -> time-varying -> 6-DOF -> sliding ->
  stick-slip.
- **memory** (``--memory``, in ``--full``): peak RSS of a 100 s run recorded every 1e-4 s.

Every section is a function returning plain dicts and lists (JSON-ready), so tests can call
them with tiny settings; `run` calls them all and `report` prints the tables. FMU runs happen
in child processes that never import the working tree's ``gearpair`` (the FMU imports its own
bundled copy, as in any host); timings there use fresh instances whose instantiation is not
counted (it is reported apart).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import importlib.util
import json
import math
import os
import platform
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

ROOT = Path(__file__).resolve().parents[2]  # repository root (build_fmu.py, examples/)
NOOP_SCRIPT = ROOT / "examples" / "bench_noop" / "GearPairNoop.py"
SCENES_DIR = ROOT / "examples" / "scenes"

REGIMES = ("no_friction", "sliding", "stick_slip")
FRICTION_OF = {"no_friction": "off", "sliding": "nominal", "stick_slip": "stick_slip"}
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "LSODA")
TARGET_ERROR = 1e-6  # DTE relative error of "equal accuracy"
TARGET_SPEEDUP = 50.0  # fast core against the fastest scipy method
TARGET_FMU_FACTOR = 1.2  # FMU <= factor * core + floor at a 1e-3 s step
TARGET_STICK_SLIP = 0.1  # s of wall time per simulated second
TARGET_MEMORY_MB = 500.0
TARGET_LADDER = 10.0  # torsional constant stiffness at least this much cheaper than stick-slip
SCIPY_MAX_EVENTS = 1000  # switches per communication step before a scipy run counts as stalled
LADDER = (
    ("torsional, constant stiffness", dict(dof="torsional", stiffness="constant",
                                           friction="off")),
    ("torsional, time-varying", dict(dof="torsional", stiffness="potential_energy",
                                     friction="off")),
    ("6-DOF, time-varying", dict(dof="full", stiffness="potential_energy", friction="off")),
    ("6-DOF + sliding friction", dict(dof="full", stiffness="potential_energy",
                                      friction="nominal")),
    ("6-DOF + stick-slip", dict(dof="full", stiffness="potential_energy",
                                friction="stick_slip")),
)


@dataclass(frozen=True)
class Settings:
    """What the benchmark runs (simulated times in s).

    Attributes
    ----------
    name : preset name
    horizon : simulated time of the fast-core and FMU work-precision runs
    windows : per regime, the simulated time of the scipy runs; errors of every method are
        compared over this common window (the stick-slip one contains the first stick at
        about 0.015 s)
    dt : output grid of the engine runs and of the reference
    fast_rtols : tolerances of the fast core
    fast_steps : communication steps of the fast core: ``dt`` (the common grid, the row
        ``fast``) and coarser ones (rows ``fast (step h)``, sampled every h)
    fast_alt_methods : other Runge-Kutta pairs of the fast core than its default DOP853
        (rows ``fast dp5``, on the common grid), to show what the choice of method buys
    scipy_rtols : per scipy method, its tolerances
    run_budget : wall-time limit (s) of one engine run of the work-precision table; a run
        that exceeds it is reported as failed
    ref_rtol : tolerance of the reference (fast core)
    check_horizon : simulated time of the cross-check of the reference against scipy DOP853
        at ``ref_rtol``; 0 skips it
    check_regimes : regimes cross-checked
    fmu_steps, fmu_rtols : communication steps and ``rtol`` parameter of the FMU rows
    step_horizon : simulated time of the costs at a 1e-3 s step (core, FMU, floor)
    calls : number of set+doStep+get calls timed per FMU
    repeats : timed runs of the cheap measurements (the best counts)
    cost_t_end : simulated time of each scene and ladder run
    ladder_repeats : rounds of the effect ladder (each runs every rung once; the best of
        each rung counts). A round costs about half a second, and neighbouring rungs differ
        by a few per cent, so it takes more rounds than ``repeats`` to rank them
    startup : measure the first instantiation with an empty and a warm numba cache
    memory : measure the peak RSS of a ``memory_t_end`` run recorded every 1e-4 s
    fmu : run the FMU sections (needs pythonfmu and fmpy)
    """

    name: str = "default"
    horizon: float = 0.1
    windows: tuple[tuple[str, float], ...] = (("no_friction", 0.005), ("sliding", 0.005),
                                              ("stick_slip", 0.02))
    dt: float = 1e-4
    fast_rtols: tuple[float, ...] = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
    fast_steps: tuple[float, ...] = (1e-4, 1e-3)
    fast_alt_methods: tuple[str, ...] = ("dp5",)
    run_budget: float = 300.0
    scipy_rtols: tuple[tuple[str, tuple[float, ...]], ...] = (
        ("RK45", (1e-5, 1e-6, 1e-7)), ("DOP853", (1e-5, 1e-6, 1e-7)),
        ("Radau", (1e-4, 1e-5)), ("LSODA", (1e-5, 1e-6)))
    ref_rtol: float = 1e-12
    check_horizon: float = 0.002
    check_regimes: tuple[str, ...] = REGIMES
    fmu_steps: tuple[float, ...] = (1e-5, 1e-4, 1e-3)
    fmu_rtols: tuple[float, ...] = (1e-8,)
    step_horizon: float = 1.0
    calls: int = 2000
    repeats: int = 3
    cost_t_end: float = 0.3
    ladder_repeats: int = 9
    startup: bool = True
    memory: bool = False
    memory_t_end: float = 100.0
    fmu: bool = True

    def window(self, regime: str) -> float:
        """Simulated time of the scipy runs (and of the common error window) of a regime."""
        return dict(self.windows)[regime]


DEFAULT = Settings()
QUICK = Settings(
    name="quick", horizon=0.004, windows=tuple((r, 0.001) for r in REGIMES),
    fast_rtols=(1e-6, 1e-9),
    scipy_rtols=(("RK45", (1e-5, 1e-6)), ("DOP853", (1e-5, 1e-6)), ("Radau", (1e-5,)),
                 ("LSODA", (1e-5,))),
    check_horizon=0.0005, check_regimes=("stick_slip",), step_horizon=0.02, calls=150,
    repeats=1, cost_t_end=0.01, ladder_repeats=1, startup=False, run_budget=60.0)
FULL = Settings(
    name="full", windows=tuple((r, 0.02) for r in REGIMES),
    fast_rtols=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11),
    scipy_rtols=(("RK45", (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)),
                 ("DOP853", (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)),
                 ("Radau", (1e-4, 1e-5, 1e-6, 1e-7)), ("LSODA", (1e-4, 1e-5, 1e-6, 1e-7))),
    check_horizon=0.02, fmu_rtols=(1e-6, 1e-8), step_horizon=2.0, calls=5000, repeats=5,
    cost_t_end=0.5, ladder_repeats=15, memory=True)
PRESETS = {"quick": QUICK, "default": DEFAULT, "full": FULL}

Progress = Callable[[str], None]


def _quiet(msg: str) -> None:
    pass


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
    commit = None
    try:
        rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=10)
        if rev.returncode == 0:
            dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain",
                                    "--untracked-files=no"], capture_output=True, text=True,
                                   timeout=10).stdout.strip()
            commit = rev.stdout.strip() + (" + uncommitted changes" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "cpu": cpu, "cores": os.cpu_count(), "usable_cores": usable, "memory_gb": mem_gb,
        "load_average": [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg")
        else None,
        "os": platform.platform(), "python": platform.python_version(),
        "numpy": np.__version__, "scipy": _version("scipy"), "numba": _version("numba"),
        "fmpy": _version("fmpy"), "pythonfmu": _version("pythonfmu"), "commit": commit,
    }


# -- runs and errors ------------------------------------------------------------------------------
def regime_effects(regime: str):
    """The `Effects` of a regime: Table 1 gear pair, potential-energy stiffness, separation,
    6-DOF; friction off, ``nominal`` (sliding) or ``stick_slip``."""
    from .effects import Effects

    return Effects(friction=FRICTION_OF[regime])


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
    from .results import simulate

    t0 = clock()
    traj = simulate(engine=engine, t_end=t_end, dt=dt)
    took = clock() - t0
    sig = {k: np.asarray(traj[k], dtype=float) for k in ("time", "dte", "mesh_force")}
    return took, sig


def _record_calls(engine, t_end: float, dt: float) -> Timing:
    """The loop an FMU master drives: one `advance` + `outputs` call per step of ``dt``, from
    the static start at the default point."""
    from .results import OperatingPoint

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
    from . import make_engine

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


def references(s: Settings, progress: Progress = _quiet) -> tuple[dict, list[dict]]:
    """Tight reference per regime (fast core at ``ref_rtol`` over the longest horizon) and
    its cross-check against scipy DOP853 at the same tolerance over ``check_horizon``.

    Returns ``(refs, checks)``: refs maps a regime to ``time``, ``dte``, ``mesh_force`` arrays
    and ``dt``; checks are rows (regime, horizon, wall times, DTE and force differences).
    """
    refs, checks = {}, []
    t_ref = max([s.horizon, *dict(s.windows).values()])
    for regime in REGIMES:
        took, sig = engine_run(regime, "fast", t_ref, s.dt, rtol=s.ref_rtol)
        refs[regime] = {**sig, "dt": s.dt, "wall_s": took.wall}
        progress(f"reference {regime}: fast core rtol {s.ref_rtol:g}, {t_ref:g} s simulated "
                 f"in {took.wall:.2f} s")
    if s.check_horizon > 0:
        for regime in s.check_regimes:
            took, sig = engine_run(regime, "reference", s.check_horizon, s.dt,
                                   rtol=s.ref_rtol, method="DOP853")
            wall = took.wall
            ref = refs[regime]
            checks.append({
                "regime": regime, "horizon_s": s.check_horizon, "rtol": s.ref_rtol,
                "dop853_wall_per_sim_s": wall / s.check_horizon,
                "fast_wall_per_sim_s": ref["wall_s"] / t_ref,
                "diff_dte": relative_error(sig["time"], sig["dte"], ref, "dte"),
                "diff_force": relative_error(sig["time"], sig["mesh_force"], ref, "mesh_force"),
            })
            progress(f"cross-check {regime}: DOP853 rtol {s.ref_rtol:g} differs by "
                     f"{checks[-1]['diff_dte']:.1e} (DTE) in {wall:.1f} s")
    return refs, checks


_NO_ERRORS = dict.fromkeys(("err_dte", "err_force", "err_dte_horizon", "err_force_horizon"),
                           math.nan)


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


def _row(regime, method, setting, rtol, step, horizon, took: Timing, errs,
         error=None) -> dict:
    return {"regime": regime, "method": method, "setting": setting, "rtol": rtol,
            "step": step, "horizon_s": horizon, "wall_s": took.wall, "cpu_s": took.cpu,
            "wall_per_sim_s": took.wall / horizon, "cpu_per_sim_s": took.cpu / horizon,
            **errs, "error": error}


_FAILED = Timing(math.nan, math.nan)


def engine_rows(s: Settings, refs: dict, progress: Progress = _quiet) -> list[dict]:
    """Work-precision rows of the fast core and of the scipy methods, every regime."""
    rows = []
    for regime in REGIMES:
        w = s.window(regime)
        for step in s.fast_steps:
            for rtol in s.fast_rtols:
                rows.append(_engine_row(regime, "fast", rtol, s.horizon, s, refs[regime],
                                        step))
        for alt in s.fast_alt_methods:
            for rtol in s.fast_rtols:
                rows.append(_engine_row(regime, f"fast {alt}", rtol, s.horizon, s,
                                        refs[regime]))
        progress(f"fast core {regime}: {len(s.fast_rtols)} tolerances")
        for method, rtols in s.scipy_rtols:
            for rtol in rtols:
                r = _engine_row(regime, method, rtol, w, s, refs[regime])
                rows.append(r)
                progress(f"scipy {method} {regime} rtol {rtol:g}: " + (
                    f"failed: {r['error']}" if r["error"] else
                    f"{r['wall_per_sim_s']:.0f} s per simulated s, DTE error "
                    f"{r['err_dte']:.1e}"))
    return rows


def _engine_row(regime: str, method: str, rtol: float, horizon: float, s: Settings,
                ref: dict, step: float | None = None) -> dict:
    """One work-precision row of an engine run; a failed run is a row with ``error``.

    ``step``: communication step (default the common output grid ``s.dt``); the fast core
    stepped at another one is the method ``fast (step h)``.
    """
    step = s.dt if step is None else step
    if method.split()[0] == "fast":
        engine, opts, repeats = "fast", {"rtol": rtol}, s.repeats
        if method != "fast":  # another Runge-Kutta pair: "fast dp5"
            opts["method"] = method.split()[1]
        if step != s.dt:
            method = f"fast (step {step:g})"
    else:
        # a stall (switches chattering at one instant) fails fast instead of running on
        engine, repeats = "reference", 1
        opts = {"rtol": rtol, "method": method, "max_events": SCIPY_MAX_EVENTS}
    try:
        with time_limit(s.run_budget):
            took, sig = engine_run(regime, engine, horizon, step, repeats, **opts)
    except (RuntimeError, ArithmeticError, ValueError) as exc:
        return _row(regime, method, f"rtol {rtol:g}", rtol, step, horizon, _FAILED,
                    _NO_ERRORS, f"{type(exc).__name__}: {exc}")
    return _row(regime, method, f"rtol {rtol:g}", rtol, step, horizon, took,
                _errors(sig, ref, s.window(regime)))


def equal_accuracy(rows: list[dict], target: float = TARGET_ERROR) -> list[dict]:
    """Per regime: each method's cheapest row (by wall time) with DTE error <= ``target``
    (None: not reached) and the ratio fastest scipy method / fast core; ``ratio_cpu`` is the
    same comparison in CPU time (each method's cheapest row by CPU time)."""
    out = []
    for regime in REGIMES:
        mine = [r for r in rows if r["regime"] == regime and r["err_dte"] <= target]
        methods = dict.fromkeys(r["method"] for r in rows if r["regime"] == regime)
        entry: dict = {"regime": regime, "target_error": target}
        for clock_key, suffix in (("wall_per_sim_s", ""), ("cpu_per_sim_s", "_cpu")):
            best: dict[str, dict | None] = {}
            for method in methods:
                ok = [r for r in mine if r["method"] == method]
                b = min(ok, key=lambda r, k=clock_key: r[k]) if ok else None
                best[method] = None if b is None else {
                    k: b[k] for k in ("setting", "rtol", "step", "wall_per_sim_s",
                                      "cpu_per_sim_s", "err_dte", "err_force")}
            scipy = {m: b for m, b in best.items() if m in SCIPY_METHODS and b is not None}
            fast = best.get("fast")
            m = min(scipy, key=lambda k, c=clock_key: scipy[k][c]) if scipy else None
            entry["best" + suffix] = best
            entry["fastest_scipy" + suffix] = m
            entry["ratio" + suffix] = None if m is None or fast is None \
                else scipy[m][clock_key] / fast[clock_key]
        out.append(entry)
    return out


def core_step_costs(s: Settings, rtols: dict[str, list[float]], step: float = 1e-3) -> list[dict]:
    """Fast core stepped at ``step`` over ``step_horizon``: loop time (best of ``repeats``)
    recording the grid in one compiled call (``wall_per_sim_s``) and with one Python
    `advance` + `outputs` call per step as an FMU master drives it
    (``calls_wall_per_sim_s``), and the one-off engine construction, per regime and
    tolerance."""
    from . import make_engine

    rows = []
    for regime in REGIMES:
        for rtol in rtols[regime]:
            t0 = time.perf_counter()
            make_engine(None, regime_effects(regime), "fast", rtol=rtol)
            build = time.perf_counter() - t0
            row = {"regime": regime, "rtol": rtol, "step": step, "horizon_s": s.step_horizon,
                   "wall_per_sim_s": None, "cpu_per_sim_s": None, "build_s": build,
                   "error": None}
            try:
                took, _ = engine_run(regime, "fast", s.step_horizon, step, s.repeats,
                                     rtol=rtol)
                row["wall_per_sim_s"] = took.wall / s.step_horizon
                row["cpu_per_sim_s"] = took.cpu / s.step_horizon
                calls = NEVER
                for _ in range(max(1, s.repeats)):
                    eng = make_engine(None, regime_effects(regime), "fast", rtol=rtol)
                    calls = calls.best(_record_calls(eng, s.step_horizon, step))
                row["calls_wall_per_sim_s"] = calls.wall / s.step_horizon
                row["calls_cpu_per_sim_s"] = calls.cpu / s.step_horizon
            except (RuntimeError, ArithmeticError, ValueError) as exc:
                row["error"] = f"{type(exc).__name__}: {exc}"
            rows.append(row)
    return rows


def engine_call_cost(n: int, step: float = 1e-3, repeats: int = 1) -> Timing:
    """Time per advance+outputs call of the fast core in the regime of the FMU call-cost
    measurement (6-DOF, constant stiffness, no friction), stepped ``step`` at a time."""
    from .effects import Effects
    from .fast import FastEngine
    from .params import OperatingPoint

    op = OperatingPoint()
    best = NEVER
    for _ in range(max(1, repeats)):
        eng = FastEngine(None, Effects(stiffness="constant", friction="off"))
        eng.reset(0.0, op.torque, op.speed)
        eng.advance(step, op.torque, op.speed)
        eng.outputs()
        t0 = clock()
        for i in range(2, n + 2):
            eng.advance(i * step, op.torque, op.speed)
            eng.outputs()
        took = clock() - t0
        best = best.best(Timing(took.wall / n, took.cpu / n))
    return best


# -- FMU (child processes) ------------------------------------------------------------------------
# Runs in a child process that never imports the working tree's gearpair. Reads a job (JSON
# file argv[1]) and writes its answers (JSON file argv[2]).
_FMU_WORKER = r"""
import importlib, json, os, sys, time
job = json.load(open(sys.argv[1]))
t_imp = time.perf_counter()
import fmpy
from fmpy.fmi2 import FMU2Slave
md = fmpy.read_model_description(job["fmu"])
unzip = fmpy.extract(job["fmu"], unzipdir=os.path.join(os.getcwd(), "extracted"))
var = {v.name: v for v in md.modelVariables}
out = {"import_s": time.perf_counter() - t_imp}

def instance():
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    s.instantiate()
    return s

def set_values(fmu, values):
    for name, x in values.items():
        v = var[name]
        if v.type == "Real":
            fmu.setReal([v.valueReference], [float(x)])
        elif v.type == "Integer":
            fmu.setInteger([v.valueReference], [int(x)])
        elif v.type == "Boolean":
            fmu.setBoolean([v.valueReference], [bool(x)])

def simulate(r):
    try:
        return simulate1(r)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}

def simulate1(r):
    best = None
    for _ in range(r["repeats"]):
        fmu = instance()
        marks = []
        def mark(t, recorder):
            marks.append((time.perf_counter(), time.process_time()))
            return True
        t0 = (time.perf_counter(), time.process_time())
        res = fmpy.simulate_fmu(unzip, model_description=md, fmu_instance=fmu, start_time=0.0,
                                stop_time=r["t_end"], output_interval=r["step"],
                                start_values=r["start"], output=r["outputs"],
                                step_finished=mark, validate=False)
        t1 = (time.perf_counter(), time.process_time())
        fmu.freeInstance()
        n = len(marks)
        # the loop: from the first step's end to the last's, scaled to all n steps
        got = {"steps": n}
        for i, key in enumerate(("", "_cpu")):
            total = t1[i] - t0[i]
            got["total_s" + key] = total
            got["loop_s" + key] = (marks[-1][i] - marks[0][i]) * n / (n - 1) if n > 1 \
                else total
        if r.get("core"):
            # the core as the FMU drives it, right after: same process, same minute
            got["core_s"], got["core_s_cpu"] = core_calls(r["core"])
        if best is None:
            best = got
        else:
            best = {k: min(v, got[k]) for k, v in best.items()}
    if r.get("signals"):
        best["signals"] = {k: [float(x) for x in res[k]] for k in ["time"] + r["signals"]}
    return best

def core_calls(c):
    # `gearpair.bench._record_calls` of the FMU's bundled package, which the FMU instances
    # imported as `_gearpair_fmu`: the loop an FMU master drives, without the FMU
    gp = sys.modules["_gearpair_fmu"]
    bench = importlib.import_module("_gearpair_fmu.bench")
    took = bench._record_calls(gp.make_engine(None, bench.regime_effects(c["regime"]), "fast",
                                              rtol=c["rtol"]), c["t_end"], c["step"])
    return took.wall, took.cpu

def init(start, step):
    fmu = instance()
    fmu.setupExperiment(startTime=0.0)
    set_values(fmu, start)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    return fmu

def calls(c):
    try:
        return calls1(c)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}

def calls1(c):
    reals = [var[n].valueReference for n in c["outputs"] if var[n].type == "Real"]
    ints = [var[n].valueReference for n in c["outputs"] if var[n].type == "Integer"]
    vin = [var["torque"].valueReference, var["speed"].valueReference]
    u = [float(c["start"]["torque"]), float(c["start"]["speed"])]
    h, n, best = c["step"], c["n"], None
    for _ in range(c["repeats"]):
        fmu = init(c["start"], h)
        fmu.setReal(vin, u)
        fmu.doStep(0.0, h)
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(1, n + 1):
            fmu.setReal(vin, u)
            fmu.doStep(i * h, h)
            fmu.getReal(reals)
            fmu.getInteger(ints)
        per = [(time.perf_counter() - t0) / n, (time.process_time() - c0) / n]
        fmu.terminate()
        fmu.freeInstance()
        best = per if best is None else [min(a, b) for a, b in zip(best, per)]
    return best

def startup(c):
    t0 = time.perf_counter()
    fmu = instance()
    t1 = time.perf_counter()
    fmu.setupExperiment(startTime=0.0)
    set_values(fmu, c["start"])
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    t2 = time.perf_counter()
    fmu.doStep(0.0, c["step"])
    t3 = time.perf_counter()
    return {"instantiate_s": t1 - t0, "initialize_s": t2 - t1, "first_step_s": t3 - t2,
            "total_s": t3 - t0}

if job.get("warmup"):
    simulate(job["warmup"])
if job.get("startup"):
    out["startup"] = startup(job["startup"])
out["runs"] = {key: simulate(r) for key, r in job.get("runs", {}).items()}
if job.get("calls"):
    out["call_s"] = calls(job["calls"])
with open(sys.argv[2], "w") as fh:
    json.dump(out, fh)
sys.stdout.flush()
sys.stderr.flush()
os._exit(0)  # skip interpreter teardown after pythonfmu slaves were loaded (docs/hosts.md)
"""


def _worker(job: dict, env: dict | None = None, timeout: float = 3600.0) -> dict:
    """Run `_FMU_WORKER` on ``job`` in a child process and return its answers."""
    with tempfile.TemporaryDirectory(prefix="gearpair_bench_") as tmp:
        jf, of = Path(tmp) / "job.json", Path(tmp) / "out.json"
        jf.write_text(json.dumps(job))
        child_env = dict(os.environ if env is None else env)
        # the child must import the FMU's bundled gearpair, never the working tree's
        child_env.pop("PYTHONPATH", None)
        proc = subprocess.run([sys.executable, "-c", _FMU_WORKER, str(jf), str(of)],
                              capture_output=True, text=True, env=child_env, cwd=tmp,
                              timeout=timeout)
        if proc.returncode != 0 or not of.is_file():
            tail = (proc.stderr or proc.stdout)[-2000:]
            raise RuntimeError(f"FMU benchmark child failed (exit {proc.returncode}): {tail}")
        return json.loads(of.read_text())


def build_fmus(outdir: str | Path) -> tuple[Path, Path]:
    """Build GearPair.fmu (build_fmu.build, current sources) and the no-op slave with the
    same variables (its ``interface.json`` is read from the GearPair modelDescription)."""
    import shutil

    import fmpy
    from pythonfmu.builder import FmuBuilder

    outdir = Path(outdir)
    spec = importlib.util.spec_from_file_location("_gearpair_bench_build_fmu",
                                                  ROOT / "build_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    gearpair_fmu = Path(mod.build(outdir))
    md = fmpy.read_model_description(str(gearpair_fmu))
    iface = [{"name": v.name, "type": v.type, "causality": v.causality,
              "variability": v.variability, "description": v.description,
              "start": None if v.start is None else
              {"Real": float, "Integer": int}.get(v.type, lambda x: x in (True, "true"))(
                  v.start)}
             for v in md.modelVariables if v.causality in ("input", "output", "parameter")]
    src = outdir / "noop_src"
    src.mkdir(parents=True, exist_ok=True)
    shutil.copy(NOOP_SCRIPT, src / NOOP_SCRIPT.name)
    (src / "interface.json").write_text(json.dumps(iface, indent=1))
    noop = Path(FmuBuilder.build_FMU(src / NOOP_SCRIPT.name, dest=outdir / "GearPairNoop.fmu",
                                     project_files=[src / "interface.json"]))
    return gearpair_fmu, noop


def fmu_start(fmu: str | Path, regime: str, rtol: float, effects=None) -> dict:
    """Start values setting an FMU with GearPair's variables up as a regime (or ``effects``)
    at the default point (3900 N.m, 100 r/min)."""
    import fmpy

    from .params import OperatingPoint
    from .scenes import Scene, Solver, fmu_start_values

    md = fmpy.read_model_description(str(fmu))
    variables = {v.name: v for v in md.modelVariables}
    fx = regime_effects(regime) if effects is None else effects
    start = fmu_start_values(Scene(name="bench", effects=fx, solver=Solver(rtol=rtol)),
                             variables)
    op = OperatingPoint()
    start.update(torque=op.torque, speed=op.speed)
    return start


def _output_names(fmu: str | Path) -> list[str]:
    import fmpy

    md = fmpy.read_model_description(str(fmu))
    return [v.name for v in md.modelVariables if v.causality == "output"]


def fmu_measurements(s: Settings, refs: dict, fmu: Path, noop: Path,
                     progress: Progress = _quiet) -> dict:
    """FMU work-precision rows, costs at a 1e-3 s step against the core (timed in the FMU's
    process) and the floor, and the cost of one set+doStep+get call (GearPair and no-op, in
    separate child processes).
    """
    from .effects import Effects

    outputs = _output_names(fmu)
    first = fmu_start(fmu, "stick_slip", s.fmu_rtols[-1])
    runs = {}
    for regime in REGIMES:
        for rtol in s.fmu_rtols:
            start = fmu_start(fmu, regime, rtol)
            for h in s.fmu_steps:
                runs[f"wp|{regime}|{rtol!r}|{h!r}"] = dict(
                    start=start, t_end=s.horizon, step=h, outputs=["dte", "mesh_force"],
                    signals=["dte", "mesh_force"], repeats=1)
            core = dict(regime=regime, rtol=rtol, t_end=s.step_horizon, step=1e-3)
            runs[f"step|{regime}|{rtol!r}"] = dict(start=start, t_end=s.step_horizon,
                                                   step=1e-3, outputs=outputs,
                                                   repeats=s.repeats, core=core)
    trivial = Effects(stiffness="constant", friction="off")
    call = dict(start=fmu_start(fmu, "no_friction", s.fmu_rtols[-1], trivial), step=1e-3,
                n=s.calls, outputs=outputs, repeats=s.repeats)
    warm = dict(start=first, t_end=0.002, step=1e-3, outputs=["dte"], repeats=1)
    progress("FMU: GearPair through fmpy (child process)")
    got = _worker({"fmu": str(fmu), "warmup": warm, "runs": runs, "calls": call})
    progress("FMU: no-op slave through fmpy (child process)")
    nstart = fmu_start(noop, "stick_slip", s.fmu_rtols[-1])
    nrun = dict(start=nstart, t_end=s.step_horizon, step=1e-3, outputs=outputs,
                repeats=s.repeats)
    ncall = dict(call, start=fmu_start(noop, "no_friction", s.fmu_rtols[-1], trivial))
    ngot = _worker({"fmu": str(noop), "warmup": dict(nrun, t_end=0.002, repeats=1),
                    "runs": {"floor": nrun}, "calls": ncall})
    rows = []
    for regime in REGIMES:
        for rtol in s.fmu_rtols:
            for h in s.fmu_steps:
                r = got["runs"][f"wp|{regime}|{rtol!r}|{h!r}"]
                setting = f"step {h:g}, rtol {rtol:g}"
                if "error" in r:
                    rows.append(_row(regime, "FMU", setting, rtol, h, s.horizon, _FAILED,
                                     _NO_ERRORS, r["error"]))
                    continue
                sig = {k: np.asarray(v) for k, v in r["signals"].items()}
                rows.append(_row(regime, "FMU", setting, rtol, h, s.horizon,
                                 Timing(r["loop_s"], r["loop_s_cpu"]),
                                 _errors(sig, refs[regime], s.window(regime))))
                rows[-1]["total_per_sim_s"] = r["total_s"] / s.horizon
    floor = ngot["runs"]["floor"]
    if "error" in floor:
        raise RuntimeError(f"the no-op FMU failed: {floor['error']}")
    steps = []
    horizon = s.step_horizon
    for regime in REGIMES:
        for rtol in s.fmu_rtols:
            r = got["runs"][f"step|{regime}|{rtol!r}"]
            row = {"regime": regime, "rtol": rtol, "step": 1e-3, "horizon_s": horizon,
                   "error": r.get("error")}
            steps.append(row)
            if row["error"]:
                continue
            # the core as the FMU drives it (one advance + outputs call per step), timed in
            # the FMU's process after each FMU run: a slow phase of a shared machine cannot
            # fall on one side of the ratio only
            for key in ("", "_cpu"):
                c = r["core_s" + key] / horizon
                fmu_x, floor_x = r["loop_s" + key] / horizon, floor["loop_s" + key] / horizon
                allowed = TARGET_FMU_FACTOR * c + floor_x
                row.update({
                    "core_per_sim_s" + key: c, "fmu_per_sim_s" + key: fmu_x,
                    "fmu_total_per_sim_s" + key: r["total_s" + key] / horizon,
                    "floor_per_sim_s" + key: floor_x,
                    "floor_total_per_sim_s" + key: floor["total_s" + key] / horizon,
                    "fmu_over_core" + key: fmu_x / c,
                    "fmu_minus_floor_over_core" + key: (fmu_x - floor_x) / c,
                    "allowed_per_sim_s" + key: allowed, "met" + key: fmu_x <= allowed})
    calls = {"n": s.calls, "step": 1e-3, "regime": "6-DOF, constant stiffness, no friction",
             "error": None}
    for key, ans in (("gearpair", got["call_s"]), ("noop", ngot["call_s"])):
        if isinstance(ans, dict):
            calls["error"], ans = ans["error"], [None, None]
        calls[key + "_s"], calls[key + "_cpu_s"] = ans
    try:
        took = engine_call_cost(s.calls, repeats=s.repeats)
        calls["engine_s"], calls["engine_cpu_s"] = took.wall, took.cpu
    except (RuntimeError, ArithmeticError) as exc:
        calls["engine_s"] = calls["engine_cpu_s"] = None
        calls["error"] = f"{type(exc).__name__}: {exc}"
    return {"rows": rows, "steps": steps, "calls": calls}


def fmu_startup(fmu: Path, progress: Progress = _quiet) -> dict:
    """Instantiate + initialize + first 1e-3 s step in a fresh process with an empty numba
    cache (the kernels compile) and again with the cache it left (they load)."""
    start = fmu_start(fmu, "stick_slip", 1e-8)
    job = {"fmu": str(fmu), "startup": {"start": start, "step": 1e-3}}
    with tempfile.TemporaryDirectory(prefix="gearpair_bench_numba_") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        progress("FMU start-up with an empty numba cache (compiles the kernels)")
        cold = _worker(job, env)["startup"]
        progress("FMU start-up with the cache just filled")
        warm = _worker(job, env)["startup"]
    return {"compile": cold, "cached": warm,
            "ratio": cold["total_s"] / warm["total_s"] if warm["total_s"] > 0 else None}


# -- memory ---------------------------------------------------------------------------------------
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
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(__file__).resolve().parents[1]), *filter(None, [env.get("PYTHONPATH")])])
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


# -- cost of effects (issue #5) -------------------------------------------------------------------
def _best_of(fn: Callable[[], Timing], repeats: int) -> tuple[Timing | None, str | None]:
    """Best of ``repeats`` calls of ``fn`` (a `Timing`), or (None, message) on failure."""
    best = NEVER
    try:
        for _ in range(max(1, repeats)):
            best = best.best(fn())
    except (RuntimeError, ArithmeticError, ValueError) as exc:
        return None, f"{type(exc).__name__}: {exc}"
    return best, None


LADDER_RUNS = (("step_1e-3", 1e-3), ("out_1e-4", 1e-4))  # communication step of the rungs


def cost_table(s: Settings, rtol: float = 1e-8, progress: Progress = _quiet) -> dict:
    """Time per simulated second of every shipped scene and of the effect ladder (fast
    engine, best of ``repeats`` for a scene and of ``ladder_repeats`` for a rung, kernels
    already loaded), with ratios to stick-slip.

    Scenes run as shipped (their step, output interval and rtol) over their first
    ``cost_t_end`` s, construction included. Ladder rungs run at the default point with
    ``rtol``, stepped every 1e-3 s (``step_1e-3``) and recorded every 1e-4 s (``out_1e-4``),
    construction excluded. Keys ``wall_<run>`` and ``cpu_<run>`` are s per simulated s.
    """
    from . import make_engine
    from .effects import Effects
    from .scenes import load_scene

    def timed_scene(scene) -> Timing:
        t0 = clock()
        scene.run("fast")
        return clock() - t0

    scenes = []
    for path in sorted(SCENES_DIR.glob("*.toml")):
        scene = load_scene(path)
        scene = scene.with_t_end(min(scene.t_end, s.cost_t_end))
        took, err = _best_of(lambda sc=scene: timed_scene(sc), s.repeats)
        fx = scene.effects
        scenes.append({"scene": scene.name, "t_end": scene.t_end, "step": scene.step,
                       "rtol": scene.solver.rtol, "dof": fx.dof,
                       "stiffness": fx.stiffness.kind, "friction": fx.friction,
                       "wall_per_sim_s": None if took is None else took.wall / scene.t_end,
                       "cpu_per_sim_s": None if took is None else took.cpu / scene.t_end,
                       "error": err})
        progress(f"scene {scene.name}: " + (f"failed: {err}" if err else
                                            f"{took.wall / scene.t_end:.3f} s per simulated s"))
    # Rungs are timed round-robin (each repeat runs every rung once; the best counts), so a
    # slow phase of this shared machine hits every rung alike instead of some rungs only.
    best: dict[tuple[str, str], Timing] = {}
    fails: dict[str, str] = {}
    for _ in range(max(1, s.ladder_repeats)):
        for label, kw in LADDER:
            if label in fails:
                continue
            fx = Effects(**kw)
            for run, dt in LADDER_RUNS:
                took, err = _best_of(
                    lambda dt=dt, fx=fx: _record(make_engine(None, fx, "fast", rtol=rtol),
                                                 s.cost_t_end, dt)[0], 1)
                if err:
                    fails[label] = err
                    break
                best[label, run] = best.get((label, run), NEVER).best(took)
    ladder = []
    for label, kw in LADDER:
        fx = Effects(**kw)
        row = {"rung": label, **kw, "error": fails.get(label)}
        for run, _dt in LADDER_RUNS:
            took = None if row["error"] else best[label, run]
            row["wall_" + run] = None if took is None else took.wall / s.cost_t_end
            row["cpu_" + run] = None if took is None else took.cpu / s.cost_t_end
        if not row["error"]:
            # the work, free of timing noise: solver steps (an exact-propagator piece counts
            # one) per simulated second, and the time per step
            from .params import OperatingPoint

            op = OperatingPoint()
            eng = make_engine(None, fx, "fast", rtol=rtol)
            eng.reset(0.0, op.torque, op.speed)
            n = int(round(s.cost_t_end / 1e-3))
            steps = rejected = 0
            for i in range(1, n + 1):
                steps += eng.advance(i * 1e-3, op.torque, op.speed).n_steps
                rejected += eng.rejected_steps
            row["steps_per_sim_s"] = steps / s.cost_t_end
            row["rejected_per_sim_s"] = rejected / s.cost_t_end
            row["us_per_step"] = 1e6 * row["wall_step_1e-3"] / row["steps_per_sim_s"]
        ladder.append(row)
        progress(f"ladder {label}: " + (f"failed: {row['error']}" if row["error"] else
                                        f"{row['wall_step_1e-3']:.3f} s per simulated s "
                                        "at 1e-3 s steps"))
    top = ladder[-1]
    checks = {}
    for run, _ in LADDER_RUNS:
        for key in ("wall_" + run, "cpu_" + run):
            for row in ladder:
                row["ratio_" + key] = None if row[key] is None or top[key] is None \
                    else row[key] / top[key]
            costs = [r[key] for r in ladder]
            ok = all(c is not None for c in costs)
            x = costs[-1] / costs[0] if ok else None
            checks[key] = {
                "increasing": ok and all(b > a for a, b in zip(costs, costs[1:], strict=False)),
                "stick_slip_over_torsional_constant": x,
                "met": x is not None and x >= TARGET_LADDER,
            }
    return {"t_end": s.cost_t_end, "rtol": rtol, "scenes": scenes, "ladder": ladder,
            "checks": checks}


# -- the whole benchmark ------------------------------------------------------------------------
def warm_up(progress: Progress = _quiet) -> float:
    """Load (or compile, about 30 s the first time) the fast engine's kernels."""
    from . import make_engine
    from .effects import Effects

    t0 = time.perf_counter()
    for fx in [regime_effects(r) for r in REGIMES] + [Effects(**kw) for _, kw in LADDER]:
        _record(make_engine(None, fx, "fast"), 0.002, 1e-3)
    wall = time.perf_counter() - t0
    progress(f"fast engine warm-up: {wall:.1f} s")
    return wall


def accurate_rtol(rows: list[dict], regime: str, target: float = TARGET_ERROR) -> float | None:
    """The loosest fast-core tolerance whose DTE error on the common grid is <= ``target``."""
    ok = [r["rtol"] for r in rows if r["regime"] == regime and r["method"] == "fast"
          and r["err_dte"] <= target]
    return max(ok) if ok else None


def _step_rtols(rows: list[dict], extra: tuple[float, ...]) -> dict[str, list[float]]:
    out = {}
    for regime in REGIMES:
        rt = set(extra)
        acc = accurate_rtol(rows, regime)
        if acc is not None:
            rt.add(acc)
        out[regime] = sorted(rt, reverse=True)
    return out


def _target(what: str, wall, cpu, limit: float, fmt: str, higher_is_better: bool = False,
            error: str | None = None) -> dict:
    """A target row: measured value in wall and CPU time, met or not, short by how much."""
    if error or wall is None:
        return {"target": what, "measured": f"run failed: {error}", "measured_cpu": None,
                "met": None, "met_cpu": None, "short_by": None}

    def ok(x):
        return None if x is None else (x >= limit if higher_is_better else x <= limit)

    factor = (limit / wall) if higher_is_better else (wall / limit)
    return {"target": what, "measured": format(wall, fmt),
            "measured_cpu": None if cpu is None else format(cpu, fmt),
            "met": ok(wall), "met_cpu": ok(cpu),
            "short_by": None if ok(wall) else f"factor {factor:.2f}"}


def targets(result: dict) -> list[dict]:
    """Each issue target: the measured value in wall time (the target's measure) and in CPU
    time (steadier on a shared machine), whether it is met and by what factor it is not."""
    out = []
    for e in result["equal_accuracy"]:
        what = (f"fast core >= {TARGET_SPEEDUP:g} x the fastest scipy method at DTE error <= "
                f"{TARGET_ERROR:g} ({e['regime']}; x)")
        out.append(_target(what, e["ratio"], e["ratio_cpu"], TARGET_SPEEDUP, ".0f", True,
                           None if e["ratio"] else "not reached by a method"))
    for st in (result.get("fmu") or {}).get("steps", []):
        what = (f"FMU at 1e-3 s <= {TARGET_FMU_FACTOR:g} x core + floor ({st['regime']}, "
                f"rtol {st['rtol']:g}; FMU / allowed)")
        if st["error"]:
            out.append(_target(what, None, None, 1.0, ".2f", error=st["error"]))
            continue
        out.append(_target(what, st["fmu_per_sim_s"] / st["allowed_per_sim_s"],
                           st["fmu_per_sim_s_cpu"] / st["allowed_per_sim_s_cpu"], 1.0, ".2f"))
    acc = accurate_rtol(result["work_precision"], "stick_slip")
    for c in result["core_steps"]:
        if c["regime"] != "stick_slip":
            continue
        tag = ", the loosest with DTE error <= 1e-6" if c["rtol"] == acc else ""
        what = (f"stick-slip: 1 simulated s in <= {TARGET_STICK_SLIP:g} s, fast core at "
                f"1e-3 s steps, rtol {c['rtol']:g}{tag} (s)")
        out.append(_target(what, c["wall_per_sim_s"], c["cpu_per_sim_s"], TARGET_STICK_SLIP,
                           ".3f", error=c["error"]))
    mem = result.get("memory")
    if mem:
        out.append(_target(f"{mem['t_end']:g} s recorded every {mem['dt']:g} s: peak RSS <= "
                           f"{TARGET_MEMORY_MB:g} MB (MB)", mem["peak_rss_mb"], None,
                           TARGET_MEMORY_MB, ".0f"))
    cost = result.get("cost")
    if cost:
        for run, what in (("step_1e-3", "1e-3 s steps"), ("out_1e-4", "output every 1e-4 s")):
            w, c = cost["checks"]["wall_" + run], cost["checks"]["cpu_" + run]
            row = _target(f"effect ladder, {what}: stick-slip / torsional constant stiffness "
                          f">= {TARGET_LADDER:g} (x)", w["stick_slip_over_torsional_constant"],
                          c["stick_slip_over_torsional_constant"], TARGET_LADDER, ".1f", True,
                          None if w["stick_slip_over_torsional_constant"] else "a rung failed")
            out.append(row)
            out.append({"target": f"effect ladder, {what}: each added effect costs more",
                        "measured": str(w["increasing"]), "measured_cpu": str(c["increasing"]),
                        "met": w["increasing"], "met_cpu": c["increasing"], "short_by": None})
    return out


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
    core = core_step_costs(s, _step_rtols(rows, s.fmu_rtols))
    progress("fast core at 1e-3 s steps: done")
    result.update(work_precision=rows, core_steps=core, fmu=None, startup=None)
    if s.fmu:
        with tempfile.TemporaryDirectory(prefix="gearpair_bench_fmu_") as tmp:
            try:  # a failing FMU section is reported, the other sections still run
                fmu, noop = build_fmus(fmu_dir or tmp)
                fm = fmu_measurements(s, refs, fmu, noop, progress)
                result["fmu"] = {"steps": fm["steps"], "calls": fm["calls"]}
                rows.extend(fm["rows"])
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


# -- output ---------------------------------------------------------------------------------------
def _fmt(x, spec: str = ".3g") -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "NO"
    if isinstance(x, float):
        return format(x, spec)
    return str(x)


def table(headers: list[str], rows: list[list]) -> str:
    """Plain-text table, columns right-aligned except the first."""
    cells = [[str(h) for h in headers]] + [[str(c) for c in r] for r in rows]
    width = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = []
    for k, r in enumerate(cells):
        lines.append("  ".join(c.ljust(width[i]) if i == 0 else c.rjust(width[i])
                               for i, c in enumerate(r)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in width))
    return "\n".join(lines)


def report(result: dict) -> str:
    """The benchmark's tables as plain text ("s/s": seconds per simulated second; "wall" and
    "CPU" are wall time and CPU time of the measuring process)."""
    m, s = result["machine"], result["settings"]
    out = [f"gearpair bench ({s['name']}), {m['date']}",
           f"machine: {m['cpu']}, {m['cores']} cores ({m['usable_cores']} usable), "
           f"{m['memory_gb']} GB; load average {m['load_average']} at start, "
           f"{m.get('load_average_end')} at end",
           f"software: {m['os']}, Python {m['python']}, numpy {m['numpy']}, scipy {m['scipy']}, "
           f"numba {m['numba']}, fmpy {m['fmpy']}, pythonfmu {m['pythonfmu']}; "
           f"commit {m['commit']}",
           f"total wall time {result['wall_s']:.0f} s", ""]
    ref = result["reference"]
    win = ", ".join(f"{r} {w:g} s" for r, w in s["windows"])
    out += [f"Reference: fast core at rtol {ref['rtol']:g}, output every {ref['dt']:g} s, "
            "from the static start at 3900 N.m, 100 r/min. Error = max|x - x_ref| / "
            f"max|x_ref| over the common window ({win}); the fast core and the FMU run "
            f"{s['horizon']:g} s ('whole run' error over all of it). Cost = time per "
            "simulated second of the stepping loop (engine built, FMU instantiated before).",
            ""]
    if ref["cross_check"]:
        out.append(table(
            ["cross-check", "simulated s", "DTE diff", "force diff", "DOP853 wall s/s",
             "fast wall s/s"],
            [[f"{c['regime']}: DOP853 vs fast, rtol {c['rtol']:g}", _fmt(c["horizon_s"]),
              _fmt(c["diff_dte"], ".1e"), _fmt(c["diff_force"], ".1e"),
              _fmt(c["dop853_wall_per_sim_s"], ".0f"), _fmt(c["fast_wall_per_sim_s"])]
             for c in ref["cross_check"]]))
        out.append("")
    for regime in REGIMES:
        rows = [r for r in result["work_precision"] if r["regime"] == regime]
        out.append(f"Work-precision, {regime} (friction {FRICTION_OF[regime]}):")
        out.append(table(
            ["method", "setting", "simulated s", "wall s/s", "CPU s/s", "DTE error",
             "force error", "DTE err whole run"],
            [[r["method"], r["setting"], _fmt(r["horizon_s"]), _fmt(r["wall_per_sim_s"]),
              _fmt(r["cpu_per_sim_s"]), _fmt(r["err_dte"], ".1e"), _fmt(r["err_force"], ".1e"),
              _fmt(r["err_dte_horizon"], ".1e")] if not r["error"] else
             [r["method"], r["setting"], _fmt(r["horizon_s"]), "failed", "-", "-", "-", "-"]
             for r in rows]))
        out += [f"  {r['method']} {r['setting']} failed: {r['error']}" for r in rows
                if r["error"]]
        out.append("")
    methods = list(dict.fromkeys(r["method"] for r in result["work_precision"]))
    for suffix, what in (("", "wall"), ("_cpu", "CPU")):
        key = "wall_per_sim_s" if not suffix else "cpu_per_sim_s"
        out.append(f"Equal accuracy, {what} time: cheapest setting with DTE error <= "
                   f"{TARGET_ERROR:g}, s/s:")
        out.append(table(
            ["regime", *methods, "scipy best / fast"],
            [[e["regime"], *[("not reached" if e["best" + suffix].get(mm) is None else
                              f"{e['best' + suffix][mm][key]:.3g} "
                              f"({e['best' + suffix][mm]['setting']})") for mm in methods],
              "-" if e["ratio" + suffix] is None else
              f"{e['ratio' + suffix]:.0f} ({e['fastest_scipy' + suffix]})"]
             for e in result["equal_accuracy"]]))
        out.append("")
    out.append(f"Fast core at 1e-3 s steps ({s['step_horizon']:g} s simulated, best of "
               f"{s['repeats']}):")
    out.append("(grid: `simulate`, one compiled call for the whole run; per call: one "
               "`advance` + `outputs` Python call per step, as an FMU master drives it)")
    out.append(table(["regime", "rtol", "wall s/s grid", "CPU s/s grid", "wall s/s per call",
                      "CPU s/s per call", "engine build s"],
                     [[c["regime"], _fmt(c["rtol"]),
                       _fmt(c["wall_per_sim_s"]) if not c["error"] else "failed",
                       _fmt(c["cpu_per_sim_s"]), _fmt(c.get("calls_wall_per_sim_s")),
                       _fmt(c.get("calls_cpu_per_sim_s")), _fmt(c["build_s"])]
                      for c in result["core_steps"]]))
    out += [f"  {c['regime']} rtol {c['rtol']:g} failed: {c['error']}"
            for c in result["core_steps"] if c["error"]]
    out.append("")
    fm = result.get("fmu")
    if fm:
        out.append(f"FMU through fmpy.simulate_fmu at a 1e-3 s step ({s['step_horizon']:g} s "
                   f"simulated, best of {s['repeats']}) against the core (per call) and the "
                   "no-op floor, "
                   "s/s; 'FMU total' adds the initialization (instantiation excluded):")
        for suffix, what in (("", "wall"), ("_cpu", "CPU")):
            out.append(table(
                ["regime", "rtol", f"core {what}", f"FMU {what}", "FMU total",
                 f"floor {what}", "FMU/core", "(FMU-floor)/core",
                 f"allowed {TARGET_FMU_FACTOR:g}xcore+floor", "met"],
                [[st["regime"], _fmt(st["rtol"]), _fmt(st.get("core_per_sim_s" + suffix)),
                  _fmt(st.get("fmu_per_sim_s" + suffix)),
                  _fmt(st.get("fmu_total_per_sim_s" + suffix)),
                  _fmt(st.get("floor_per_sim_s" + suffix)),
                  _fmt(st.get("fmu_over_core" + suffix), ".2f"),
                  _fmt(st.get("fmu_minus_floor_over_core" + suffix), ".2f"),
                  _fmt(st.get("allowed_per_sim_s" + suffix)), _fmt(st.get("met" + suffix))]
                 for st in fm["steps"]]))
        out += [f"  {st['regime']} failed: {st['error']}" for st in fm["steps"] if st["error"]]
        c = fm["calls"]

        def us(key):
            w, cpu = c[key + "_s"], c[key + "_cpu_s"]
            return "failed" if w is None else f"{w * 1e6:.0f} us ({cpu * 1e6:.0f} us CPU)"

        out.append(f"One setReal+doStep(1e-3 s)+getReal+getInteger call ({c['regime']}, "
                   f"{c['n']} calls): GearPair {us('gearpair')}, no-op {us('noop')}; the "
                   f"engine's own advance+outputs {us('engine')}.")
        if c["error"]:
            out.append(f"  failed: {c['error']}")
        out.append("")
    if result.get("fmu_error"):
        out += [f"FMU section failed: {result['fmu_error']}", ""]
    st = result.get("startup")
    if st:
        out.append("FMU first instantiation + initialization + first step (fresh process):")
        out.append(table(
            ["numba cache", "instantiate s", "initialize s", "first step s", "total s"],
            [[k, _fmt(v["instantiate_s"]), _fmt(v["initialize_s"]), _fmt(v["first_step_s"]),
              _fmt(v["total_s"])] for k, v in (("empty (compile)", st["compile"]),
                                               ("warm (cached)", st["cached"]))]))
        out.append("")
    cost = result.get("cost")
    if cost:
        out.append(f"Cost of the shipped scenes (fast engine, first {cost['t_end']:g} s, "
                   "their own step and rtol):")
        out.append(table(["scene", "simulated s", "step s", "dof", "stiffness", "friction",
                          "wall s/s", "CPU s/s"],
                         [[r["scene"], _fmt(r["t_end"]), _fmt(r["step"]), r["dof"],
                           r["stiffness"], r["friction"],
                           "failed" if r["error"] else _fmt(r["wall_per_sim_s"]),
                           _fmt(r["cpu_per_sim_s"])] for r in cost["scenes"]]))
        out += [f"  {r['scene']} failed: {r['error']}" for r in cost["scenes"] if r["error"]]
        out.append("")
        out.append(f"Effect ladder (fast engine, rtol {cost['rtol']:g}, 3900 N.m, 100 r/min, "
                   f"{cost['t_end']:g} s simulated), s/s and ratio to stick-slip:")
        heads, cols = ["rung"], []
        for run, what in (("step_1e-3", "1e-3 s steps"), ("out_1e-4", "output 1e-4 s")):
            for clk in ("wall", "cpu"):
                heads += [f"{clk} {what}", "ratio"]
                cols += [f"{clk}_{run}"]
        heads += ["steps/s", "rejected/s", "us/step"]
        out.append(table(heads, [[r["rung"], *[x for k in cols for x in (
            _fmt(r[k]), _fmt(r["ratio_" + k], ".2f"))], _fmt(r.get("steps_per_sim_s"), ".3g"),
            _fmt(r.get("rejected_per_sim_s"), ".3g"), _fmt(r.get("us_per_step"))]
            for r in cost["ladder"]]))
        out += [f"  {r['rung']} failed: {r['error']}" for r in cost["ladder"] if r["error"]]
        out.append("")
    mem = result.get("memory")
    if mem:
        out.append(f"Memory: {mem['t_end']:g} s simulated, recorded every {mem['dt']:g} s "
                   f"({mem['samples']} samples, {mem['trajectory_mb']:.0f} MB of arrays): peak "
                   f"RSS {mem['peak_rss_mb']:.0f} MB (after imports {mem['baseline_rss_mb']:.0f}"
                   f" MB), {mem['wall_s']:.0f} s of wall time.")
        out.append("")
    out.append("Targets (measured in wall time, the target's measure, and in CPU time):")
    out.append(table(["target", "wall", "met", "CPU", "met (CPU)", "short by (wall)"],
                     [[t["target"], _fmt(t["measured"]), _fmt(t["met"]),
                       _fmt(t["measured_cpu"]), _fmt(t["met_cpu"]), _fmt(t["short_by"])]
                      for t in result["targets"]]))
    return "\n".join(out)


def plot(result: dict, path: str | Path, clock: str = "wall") -> None:
    """Work-precision diagram: error against time per simulated second (log-log; ``clock``
    "wall" or "cpu"), DTE (top) and mesh force (bottom), one panel per regime, one line per
    method."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError("--plot needs matplotlib: pip install 'gearpair[plot]'") from None
    fig = Figure(figsize=(13.0, 7.5), layout="constrained")
    ax = fig.subplots(2, len(REGIMES), sharex=True, sharey="row")
    markers = {"fast": "o", "fast dp5": "x", "RK45": "s", "DOP853": "D", "Radau": "^",
               "LSODA": "v", "FMU": "*"}  # by the method, else its first word
    rows = result["work_precision"]
    for j, regime in enumerate(REGIMES):
        mine = [r for r in rows if r["regime"] == regime]
        lines: dict[str, list[dict]] = {}
        for r in mine:
            key = r["method"] if r["method"] != "FMU" else f"FMU rtol {r['rtol']:g}"
            lines.setdefault(key, []).append(r)
        for i, err in enumerate(("err_dte", "err_force")):
            a = ax[i, j]
            for key, rs in lines.items():
                # along the setting: loose to tight tolerance, coarse to fine FMU step
                rs = sorted((r for r in rs if not r["error"]),
                            key=lambda r: (-r["step"], -r["rtol"]) if key.startswith("FMU")
                            else (-r["rtol"], -r["step"]))
                x = [r[f"{clock}_per_sim_s"] for r in rs]
                y = [max(r[err], 1e-16) for r in rs]
                a.loglog(x, y, marker=markers.get(key, markers.get(key.split()[0], "o")),
                         ms=4, lw=1, label=key)
                if key.startswith("FMU"):
                    for r, xx, yy in zip(rs, x, y, strict=True):
                        a.annotate(f"h={r['step']:g}", (xx, yy), fontsize=6,
                                   textcoords="offset points", xytext=(3, 3))
            a.axhline(TARGET_ERROR, color="0.5", lw=0.8, ls="--")
            a.grid(True, which="both", lw=0.3)
            if i == 0:
                a.set_title(f"{regime} (friction {FRICTION_OF[regime]})")
            else:
                a.set_xlabel(f"{'CPU' if clock == 'cpu' else 'wall'} time per simulated "
                             "second (s)")
        ax[0, j].legend(fontsize="small")
    ax[0, 0].set_ylabel("DTE error (relative)")
    ax[1, 0].set_ylabel("mesh force error (relative)")
    m = result["machine"]
    fig.suptitle(f"gearpair work-precision, {m['cpu']} ({m['cores']} cores), "
                 f"{m['date'][:10]}")
    fig.savefig(Path(path), dpi=120)


# -- command line ---------------------------------------------------------------------------------
def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``bench`` on a subparsers object (the ``gearpair`` command line)."""
    p = sub.add_parser("bench", help="work-precision, FMU cost and cost-per-effect tables "
                       "(docs/bench.md)", description=__doc__.splitlines()[0])
    size = p.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help="tiny horizons, for tests")
    size.add_argument("--full", action="store_true", help="longer runs, more tolerances, "
                      "memory (tens of minutes)")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--plot", metavar="FILE", help="draw the work-precision diagram (needs "
                   "matplotlib)")
    p.add_argument("--memory", action="store_true", help="also measure the peak RSS of a "
                   "100 s run (slow; included in --full)")
    p.add_argument("--no-fmu", action="store_true", help="skip the FMU sections")
    p.add_argument("--no-startup", action="store_true", help="skip the FMU compile/cached "
                   "start-up measurement")
    p.add_argument("--step-horizon", type=float, metavar="S", help="simulated time of the "
                   "1e-3 s step costs (core, FMU, floor); default 1 s (0.02 s with --quick)")
    return p


def jsonable(x):
    """``x`` with numpy scalars as Python numbers and NaN/inf as None (strict JSON)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x


def settings_from(args: argparse.Namespace) -> Settings:
    """The `Settings` of the command line options (a preset, then the overrides)."""
    s = QUICK if args.quick else FULL if args.full else DEFAULT
    if args.memory:
        s = replace(s, memory=True)
    if args.no_fmu:
        s = replace(s, fmu=False)
    if args.no_startup:
        s = replace(s, startup=False)
    if args.step_horizon is not None:
        if not (math.isfinite(args.step_horizon) and 0.0 < args.step_horizon <= 100.0):
            raise ValueError(f"--step-horizon = {args.step_horizon!r} must be in (0, 100] s")
        s = replace(s, step_horizon=float(args.step_horizon))
    return s


def main(argv: list[str] | argparse.Namespace | None = None) -> int:
    """``gearpair bench``: run, print the tables (or JSON), optionally draw the diagram."""
    if isinstance(argv, argparse.Namespace):
        args = argv
    else:
        ap = argparse.ArgumentParser(prog="gearpair")
        add_parser(ap.add_subparsers(dest="cmd", required=True))
        args = ap.parse_args(["bench", *(sys.argv[1:] if argv is None else argv)])
    s = settings_from(args)
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    result = run(s, progress)
    if args.plot:
        try:
            plot(result, args.plot)
        except ImportError as exc:
            print(f"gearpair: error: {exc}", file=sys.stderr)
            return 1
        result["plot"] = args.plot
    if args.json:
        print(json.dumps(jsonable(result), indent=1, allow_nan=False))
    else:
        print(report(result))
        if args.plot:
            print(f"\nwork-precision diagram written to {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
