"""``gearpair sweep``: its options, the grid from the arguments, and the command (checks
first, then the points into the store, then the files and the report). The sweep itself is
`gearpair.sweep`, imported when the command runs, apart from the settings' defaults."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

from ..params import RTOL_MIN
from ..sweep.grid import Grid
from ..sweep.settings import SweepSettings
from .common import add_effect_options, effects_from_args, parse_set


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``gearpair sweep`` on an argparse subparsers object."""
    s = sub.add_parser(
        "sweep", help="stick/contact-loss ratios and bifurcation data over parameter grids "
        "(dask), stored as the points finish, resumable",
        description="Sweep one parameter (PARAM VALUES) or a grid (NAME=VALUES ..., the full "
                    "factorial; or --points FILE.csv). Every point goes to the store "
                    "(--store, default PREFIX.zarr) as it finishes; the same command again "
                    "resumes. One parameter also writes PREFIX.csv, PREFIX_poincare.csv, "
                    "PREFIX.json and PREFIX.png; a grid PREFIX.json and maps PREFIX_map*.png. "
                    "Examples: gearpair sweep speed_rpm 5:600:300 --out speed; gearpair sweep "
                    "speed_rpm=5:600:120 torque=1000:4000:7 mu=0.01,0.02,0.03 --out grid")
    s.add_argument("grid", nargs="*", metavar="PARAM VALUES | NAME=VALUES",
                   help="what to sweep: PARAM VALUES (one parameter) or NAME=VALUES ... (the "
                   "full factorial). A name is speed_rpm (r/min), torque (N.m) or a "
                   "GearParams field in SI units (e.g. mu, kb1, module); VALUES is a,b,c or "
                   "start:stop:num (num evenly spaced values, both ends included)")
    s.add_argument("--points", metavar="FILE.csv", help="an explicit list of points instead: "
                   "a header of parameter names, one row per point")
    s.add_argument("--out", default="sweep", metavar="PREFIX", help="output prefix: one "
                   "parameter writes PREFIX.csv, PREFIX_poincare.csv, PREFIX.json, PREFIX.png; "
                   "a grid PREFIX.json and PREFIX_map*.png (the folder is created; checked for "
                   "writing before the run); default sweep")
    s.add_argument("--store", metavar="PATH.zarr", help="the Zarr store every point goes to "
                   "as it finishes (xarray.open_zarr reads it); an existing store of the same "
                   "sweep is resumed; default PREFIX.zarr")
    s.add_argument("--new-store", action="store_true", help="replace a store that holds "
                   "another sweep (other grid, settings or engine version) by a new one; "
                   "default: refuse, naming the difference")
    s.add_argument("--rerun-failed", action="store_true", help="run the points stored as "
                   "failed or invalid again; default: keep them")
    s.add_argument("--slice", action="append", default=[], metavar="NAME=VALUE",
                   help="for grids of three or more parameters: draw only the maps at this "
                   "value of NAME (the nearest grid value); repeatable; default: one map per "
                   "combination of the other parameters' values")
    s.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running dask scheduler (tcp://host:port); 'serial' runs "
                   "in this process; default: a local cluster of --workers processes")
    s.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes; default: the number of CPU cores")
    s.add_argument("--retries", type=int, default=1, metavar="N",
                   help="reruns of a failed point, each with a ten times tighter rtol; "
                   "default 1")
    add_settings_options(s)
    s.add_argument("--no-plot", action="store_true", help="do not draw PREFIX.png; default: "
                   "draw it (needs matplotlib)")
    s.add_argument("--quiet", action="store_true", help="no progress bar and no messages on "
                   "stderr (errors still go there)")
    return s


def add_settings_options(s) -> None:
    """The options of what every point holds (`SweepSettings`): the held torque and speed,
    ``--set``, the engine's tolerance, the durations and the effects; `settings_from_args`
    reads them (``gearpair sweep`` and ``gearpair sensitivity``)."""
    from ..params import RTOL_MAX

    d = SweepSettings()
    s.add_argument("--torque", type=float, default=d.torque, metavar="NM",
                   help=f"driving torque on gear 1 when not swept (N.m); default {d.torque:g}")
    s.add_argument("--speed-rpm", type=float, default=d.speed_rpm, metavar="RPM",
                   help=f"speed of gear 1 when not swept (r/min); default {d.speed_rpm:g}")
    s.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="change a GearParams field (SI), e.g. --set mu=0.03; repeatable; "
                   "default: Table 1")
    s.add_argument("--rtol", type=float, default=d.rtol,
                   help=f"relative tolerance of the fast engine, [{RTOL_MIN:g}, "
                   f"{RTOL_MAX:g}]; default {d.rtol:g}")
    s.add_argument("--steps-per-period", type=int, default=d.steps_per_period, metavar="N",
                   help="engine steps (samples) per mesh period for the DTE and mesh force "
                   f"statistics; default {d.steps_per_period}")
    s.add_argument("--transient-periods", type=int, default=d.transient_periods, metavar="N",
                   help=f"mesh periods discarded before the kept ones; default "
                   f"{d.transient_periods}")
    s.add_argument("--transient-time", type=float, default=d.transient_time, metavar="S",
                   help=f"discard at least this many seconds (s); default {d.transient_time:g}")
    s.add_argument("--kept-periods", type=int, default=d.kept_periods, metavar="N",
                   help=f"mesh periods kept for ratios and the Poincare section; default "
                   f"{d.kept_periods}")
    s.add_argument("--max-time", type=float, default=d.max_time, metavar="S",
                   help="soft cap of simulated seconds per point (s; both period counts are "
                   f"cut, never below {d.min_periods}); default {d.max_time:g}")
    add_effect_options(s.add_argument_group("effects of every point (docs/scenes.md "
                                            "[effects])"))


def settings_from_args(args) -> SweepSettings:
    """The held settings; ``--set`` and the effect options are read as ``modes`` and
    ``simulate`` read them (`common.parse_set`: the closest name for a typo, whole numbers
    where needed; `common.effects_from_args`: a refused combination raises ``ValueError``)."""
    return SweepSettings(
        torque=args.torque, speed_rpm=args.speed_rpm,
        params=tuple(parse_set(args.set).items()),
        **effects_from_args(args).values(), rtol=args.rtol,
        steps_per_period=args.steps_per_period, transient_periods=args.transient_periods,
        transient_time=args.transient_time, kept_periods=args.kept_periods,
        max_time=args.max_time)


def grid_from_args(args) -> Grid:
    """The points: ``PARAM VALUES`` (one parameter), ``NAME=VALUES ...`` or ``--points``."""
    specs = list(args.grid)
    if args.points:
        if specs:
            raise ValueError("give either --points FILE.csv or parameters, not both")
        return Grid.from_csv(args.points)
    if not specs:
        raise ValueError("empty grid: give PARAM VALUES, NAME=VALUES ... or --points FILE.csv")
    if any("=" in x for x in specs):
        bad = [x for x in specs if "=" not in x]
        if bad:
            raise ValueError(f"{bad[0]!r}: in a grid every parameter is NAME=VALUES")
        return Grid.parse(specs)
    if len(specs) != 2:
        raise ValueError(f"{' '.join(specs)!r}: use PARAM VALUES (one parameter) or "
                         "NAME=VALUES ... (a grid)")
    return Grid.product({specs[0]: specs[1]})


def _warn_heaviest_load(grid: Grid, settings: SweepSettings) -> None:
    """The heaviest tooth load of the sweep, once, before the run (a GearDataWarning)."""
    from ..geometry import unit_load, warn_implausible_load

    points = [settings.inputs_at(p) for _, p in grid.points()]
    p, _, torque, _ = max(points, key=lambda pt: unit_load(pt[0], pt[2]))
    warn_implausible_load(p, torque)


def run(args) -> int:
    """``gearpair sweep``: check everything, run the missing points into the store, write the
    files, report the cost. Exit status 1 when a point failed or was invalid (it is in the
    store and the files with its error), 130 when interrupted (the finished points are
    stored), 2 for bad input (nothing ran)."""
    from ..sweep import study
    from ..sweep.store import Store

    settings = settings_from_args(args)
    # Check names and the held values here, so a typo fails before a cluster starts.
    settings.inputs("speed_rpm", settings.speed_rpm)
    grid = grid_from_args(args)
    study.check_grid(grid, settings)
    _warn_heaviest_load(grid, settings)
    # every output file before the run, not after it (`SweepResult.write` names them)
    from ..writable import check_writable

    prefix = Path(args.out)
    one = grid.kind == "product" and len(grid.names) == 1
    names = [prefix.with_suffix(".json")]
    if one:
        names += [prefix.with_suffix(".csv"), Path(f"{prefix}_poincare.csv")]
        names += [] if args.no_plot else [prefix.with_suffix(".png")]
    for name in names:
        check_writable("--out", name, shown=args.out)
    slices = parse_slices(args.slice, grid)
    store = Path(args.store) if args.store else Path(f"{prefix}.zarr")
    st = Store.open_or_create(store, grid, settings, new=args.new_store)  # before any point
    try:
        return _run_and_report(args, grid, settings, st, store, prefix, one, slices)
    finally:
        st.close()


def _run_and_report(args, grid, settings, st, store, prefix, one, slices) -> int:
    """Run the missing points into the open store ``st``, write the files, report."""
    from ..sweep import study
    from ..sweep.plot import plot_maps
    from ..sweep.result import SweepResult

    run = study.run_grid(grid, settings, st, scheduler=args.scheduler, workers=args.workers,
                         retries=args.retries, rerun_failed=args.rerun_failed,
                         progress=not args.quiet)
    recs = st.records()
    files: dict[str, Any] = {"store": str(store)}
    summary = run.summary()
    lines = [run.report()]
    if run.after.get("not_run", 0) == 0:
        if one:
            res = SweepResult(grid.names[0], list(grid.values[0]), settings, recs,
                              run.elapsed_s, run.startup_s, run.workers, run.scheduler,
                              run.retried, extra={"store": str(store)})
            files.update(res.write(args.out, plot=not args.no_plot))
            # the one-parameter report and JSON as before, with the run's counts beside
            lines = [res.report(), run.report()]
            summary = {**{k: v for k, v in res.summary().items() if k != "settings"},
                       **{k: v for k, v in summary.items() if k not in ("elapsed_s",
                                                                         "startup_s")}}
        else:
            js = prefix.with_suffix(".json")
            js.write_text(json.dumps({**summary, "settings": asdict(settings)},
                                     indent=2, default=str))
            files["json"] = str(js)
            if not args.no_plot and len(grid.names) >= 2:
                files["maps"] = [str(p) for p in plot_maps(store, prefix, slices)]
            for r in recs:
                if r["status"] in ("failed", "invalid"):
                    where = ", ".join(f"{n} = {v:g}"
                                      for n, v in grid.point(r["index"]).items())
                    lines.append(f"  {r['status'].upper()} point {r['index']} ({where}): "
                                 f"{r['error']}")
    if not args.quiet:
        print("\n".join(lines), file=sys.stderr)
    print(json.dumps({"files": files, **summary}, indent=2, default=str))
    if run.interrupted:
        return 130
    return 1 if run.after.get("failed", 0) or run.after.get("invalid", 0) else 0


def parse_slices(items: list[str], grid: Grid) -> dict[str, float]:
    """``--slice NAME=VALUE`` items: names of the grid, values as numbers."""
    out: dict[str, float] = {}
    for item in items:
        k, sep, v = item.partition("=")
        k = k.strip()
        if not sep or k not in grid.names:
            raise ValueError(f"--slice {item!r}: use NAME=VALUE with NAME one of "
                             + ", ".join(grid.names))
        try:
            out[k] = float(v)
        except ValueError:
            raise ValueError(f"--slice {item!r}: {v.strip()!r} is not a number") from None
    return out
