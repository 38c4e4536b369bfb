"""Parameter sweeps on dask: stick and contact-loss ratios and Poincare sections of the DTE.

One sweep point is one run of the fast engine at one value of one parameter (the speed, the
torque or any `GearParams` field) with everything else held. Each point returns

- the stick ratio ``r_k = t_k / t_t`` and contact-loss ratio ``r_l = t_l / t_t`` (Eqs. (26)-(27);
  Figs. 15, 17, 18) over the kept mesh periods, from the engine's located switching instants;
- the Poincare section of the DTE (Eq. (3)): one sample per mesh period
  ``T_m = 2 pi / (z1 Omega1)`` over the kept periods, at a fixed phase of the period
  (``section_phase``; Fig. 16), with the period of the response in mesh periods (1, 2, ...;
  0 none found up to ``max_period``) and the number of distinct values;
- the mesh force over the whole trajectory of the kept periods: its time mean from the
  engine's integral over every integrator step (`StepSummary.mesh_force_mean`), its least and
  peak values from the engine's dense samples inside every step; the back-flank contact ratio
  (with backlash: contact under a negative torque, not contact loss);
- DTE statistics at the ``steps_per_period`` samples per period, named ``_sampled`` (a mean
  over samples at fixed phases of the mesh period is not the time mean), adjacent-period
  differences, the half-order amplitude of the DTE (Fig. 14), and the cost of the point (wall
  and CPU time, worker).

Durations are counted in mesh periods: ``transient_periods`` are discarded (at least
``transient_time`` seconds: the slowest mode, 32 Hz at damping ratio 0.02, decays with a time
constant of 0.25 s) and ``kept_periods`` are kept. At low speed a mesh period is long, so the
simulated time is capped at about ``max_time`` seconds by cutting both counts, never below
``min_periods`` each; the counts used are in the output.

Points run in parallel on dask.distributed: a `LocalCluster` of worker processes by default
(one thread each: the engine is single-threaded compiled code), or an existing cluster by its
scheduler address. A point that raises is caught inside the task and returned as an error
record; it is retried (``retries`` times, each with a ten times tighter ``rtol``) and, if it
still fails, kept in the output with ``status = failed`` and the error. A worker that dies is
treated the same way. A point whose value the parameter validation refuses, or that lies
outside the model's validity (a negative torque without backlash: the teeth part for good),
is not run and not retried: ``status = invalid`` with the reason. Nothing is dropped.

``gearpair sweep`` is the command line (`gearpair.cli.sweep`).

The package holds one concern per module: `settings` (what is held and what may vary),
`grid` (the points), `point` (one point), `run` (serial or dask execution), `store` (the Zarr
store written as points finish), `study` (a grid into a store, resumable), `progress`,
`result` (a one-parameter sweep and its files) and `plot`.
"""

from __future__ import annotations

from .grid import Grid, parse_values
from .plot import plot_maps, plot_sweep, sweep_title
from .point import COLUMNS, record_periods, run_point
from .progress import Progress
from .result import SweepResult, read_csv, read_poincare_csv, read_result
from .run import local_cluster, run_sweep
from .sensitivity import Dist, open_indices, parse_ranges, plot_indices, run_sensitivity
from .settings import INPUTS, SweepSettings, outside_validity, sweepable
from .store import Store, StoreError, open_dataset
from .study import StudyRun, run_grid

__all__ = [
    "COLUMNS", "INPUTS", "Grid", "Progress", "Store", "StoreError", "StudyRun", "SweepResult",
    "SweepSettings", "local_cluster", "open_dataset", "outside_validity",
    "parse_values", "plot_maps", "plot_sweep", "read_csv", "read_poincare_csv", "read_result",
    "record_periods", "run_grid", "run_point", "run_sweep",
    "sweep_title", "sweepable", "Dist", "open_indices", "parse_ranges", "plot_indices",
    "run_sensitivity",
]

