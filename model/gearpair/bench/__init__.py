"""Benchmark: work-precision of the integrators, cost of the FMU and cost of each effect.

``gearpair bench [--quick | --full] [--json] [--plot FILE] [--memory] [--fmu PATH]``
measures in one run, side by side on the same machine:

- **work-precision** for four regimes at the paper's low-speed point (3900 N.m, 100 r/min):
  no friction, sliding (Coulomb friction in the nominal direction, no stick) and stick-slip
  with the paper's potential-energy stiffness, and stick-slip with rectangular stiffness
  (``stick_slip_rectangular``, work-precision and equal accuracy only).
  Every method starts from the static equilibrium at t = 0 and records DTE and mesh force on
  the same output grid; the error is the largest deviation from a tight reference divided by
  the reference's largest magnitude, the cost the wall time (and the CPU time) per simulated
  second. Methods: the fast core (`gearpair.fast.FastEngine`) at several tolerances, with its
  default DOP853 and with Dormand-Prince 5(4) (rows ``fast dp5``); scipy's
  RK45, DOP853, Radau and LSODA, run as `gearpair.reference.ReferenceEngine` (scipy's
  ``OdeSolver`` classes, which ``solve_ivp`` drives, stepped segment by segment over the same
  physics); the same four as a user would write the model, `plain_scipy` (rows
  ``plain <method>``: a right-hand side in Python floats per contact state, ``solve_ivp``
  with terminal events); the FMU through fmpy at communication steps 1e-5, 1e-4 and 1e-3 s.
- **equal accuracy**: per method the cheapest setting with DTE error <= 1e-6 over the
  window and the whole run, and the ratios fastest scipy method / fast core, on the
  reference engine and written plainly (the claim: both sides, their settings and errors).
- **FMU cost** at a 1e-3 s step against the core at the same step (driven as the FMU drives
  it: one ``advance`` + ``outputs`` call per step) and the plumbing floor (the
  same fmpy call on a pythonfmu slave that does nothing, ``GearPairNoop.py`` beside this
  module, run on GearPair.fmu's own binary); the cost of one set+doStep+get call; the first
  instantiation with empty caches (the FMU's shipped code) against warm ones and, outside
  ``--quick``, with ``GEARPAIR_SHIPPED_CODE=0`` (compile).
- **the FMU in a C master**: per-step cost of set 2 inputs + doStep + get 4
  outputs at 1e-4 and 1e-3 s steps in ``fmi2_bench_host.c`` (beside this module) beside
  fmpy's, with the no-op slave and the engine's own work, and the first start with empty and
  warm caches (skipped without gcc); GearPair3.fmu (FMI 3.0) against GearPair.fmu in
  ``fmi3_bench_host.c`` at 1e-4 s steps, without early return and with it (early returns
  per simulated second and their cost), and, outside ``--quick``, GearPair.fmu's win64 DLL
  under Wine against its linux64 binary (information; skipped without Wine or mingw-w64).
- **cost of effects**: wall time per simulated second of every example scene (the folder
  ``examples/scenes`` of the current directory, or ``--scenes DIR``; skipped with a note
  without one) and
  of the effect ladder torsional constant stiffness -> time-varying -> 6-DOF -> sliding ->
  stick-slip.
- **memory** (``--memory``, in ``--full``): peak RSS of a 100 s run recorded every 1e-4 s.

The FMU is the one `gearpair.scenes.location.find_fmu` finds (``--fmu PATH``, else
``$GEARPAIR_FMU``, else ``dist/GearPair.fmu`` of the current directory, rebuilt there when
stale), so the package needs no repository: its own files (the no-op slave, the C host, the
plain scipy model) ship inside it.

Every section is a function returning plain dicts and lists (JSON-ready), so tests can call
them with tiny settings; `run` calls them all and `report` prints the tables. Measuring and
reporting live apart: `settings` (presets, targets), `runs` (timing an engine, errors),
`work_precision`, `plain`, `fmu`, `chost`, `effect_cost`, `memory` and `measure` (the
whole run) measure; `targets`, `report` and `plot` judge and show; `gearpair.cli.bench` is
the command line. FMU runs happen in child processes that never import the working tree's
``gearpair`` (the FMU imports its own bundled copy, as in any host); timings there use fresh
instances whose instantiation is not counted (it is reported apart).
"""

from __future__ import annotations

from .chost import build_host, host_measurements, run_host
from .effect_cost import LADDER_RUNS, cost_table
from .fmi3 import fmi3_measurements, wine_measurements
from .fmu import build_noop, fmu_measurements, fmu_start, fmu_startup
from .measure import run, warm_up
from .memory import memory_peak
from .plain import plain_rows
from .plot import plot
from .report import jsonable, report, table
from .runs import (
    NEVER,
    BudgetExceeded,
    Timing,
    _record,
    _record_calls,
    clock,
    engine_run,
    machine_info,
    regime_effects,
    relative_error,
    time_limit,
)
from .settings import (
    DEFAULT,
    FMI3_HOST_SOURCE,
    FRICTION_OF,
    FULL,
    HOST_SOURCE,
    LADDER,
    NOOP_SCRIPT,
    PLAIN_PREFIX,
    PRESETS,
    QUICK,
    RECTANGULAR,
    REGIMES,
    SCENES_DIR,
    SCIPY_MAX_EVENTS,
    SCIPY_METHODS,
    STIFFNESS_OF,
    TARGET_ERROR,
    TARGET_FIRST_START_S,
    TARGET_FMU_FACTOR,
    TARGET_LADDER,
    TARGET_MEMORY_MB,
    TARGET_SPEEDUP,
    TARGET_STICK_SLIP,
    WP_REGIMES,
    Settings,
)
from .targets import targets
from .work_precision import (
    accurate_rtol,
    core_step_costs,
    engine_call_cost,
    engine_rows,
    equal_accuracy,
    references,
)

__all__ = [
    "DEFAULT", "FMI3_HOST_SOURCE", "FRICTION_OF", "FULL", "HOST_SOURCE", "LADDER",
    "LADDER_RUNS", "NEVER",
    "NOOP_SCRIPT", "PLAIN_PREFIX", "PRESETS", "QUICK", "RECTANGULAR", "REGIMES",
    "SCENES_DIR", "SCIPY_MAX_EVENTS", "SCIPY_METHODS", "STIFFNESS_OF", "TARGET_ERROR",
    "TARGET_FIRST_START_S", "WP_REGIMES",
    "TARGET_FMU_FACTOR", "TARGET_LADDER", "TARGET_MEMORY_MB",
    "TARGET_SPEEDUP", "TARGET_STICK_SLIP", "_record", "_record_calls", "accurate_rtol",
    "BudgetExceeded", "build_host", "build_noop", "clock", "core_step_costs",
    "cost_table", "engine_call_cost", "engine_rows", "engine_run", "equal_accuracy",
    "fmi3_measurements", "fmu_measurements", "fmu_start", "fmu_startup", "host_measurements",
    "jsonable",
    "machine_info", "memory_peak", "plain_rows", "plot", "references",
    "regime_effects", "relative_error", "report", "run", "run_host", "Settings",
    "table", "targets", "time_limit", "Timing", "warm_up", "wine_measurements",
]
