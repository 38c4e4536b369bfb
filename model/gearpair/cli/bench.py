"""``gearpair bench``: options, presets and the printed or JSON output (the measuring is
`gearpair.bench`, imported when the command runs)."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

from .common import check_figure_format

DESCRIPTION = ("Benchmark: work-precision of the integrators, cost of the FMU and cost of "
               "each effect.")


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``bench`` on a subparsers object (the ``gearpair`` command line)."""
    p = sub.add_parser("bench", help="work-precision, FMU cost and cost-per-effect tables "
                       "(docs/bench.md)", description=DESCRIPTION)
    size = p.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help="tiny horizons, for tests "
                      "(about 11 s; the first run after an engine change also compiles the "
                      "engine and the FMU's copy of it side by side, about 30 s, and says so)")
    size.add_argument("--full", action="store_true", help="longer runs, more tolerances, "
                      "memory (tens of minutes)")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--plot", metavar="FILE", help="draw the work-precision diagram (needs "
                   "matplotlib)")
    p.add_argument("--memory", action="store_true", help="also measure the peak RSS of a "
                   "100 s run (slow; included in --full)")
    p.add_argument("--fmu", metavar="PATH", help="the GearPair FMU to measure; default "
                   "$GEARPAIR_FMU, else dist/GearPair.fmu of the current folder (where "
                   "build_fmu.py writes it), rebuilt when stale")
    p.add_argument("--no-fmu", action="store_true", help="skip the FMU sections")
    p.add_argument("--scenes", metavar="DIR", help="the folder of scenes (*.toml) whose cost "
                   "is timed; default examples/scenes of the current folder (the repository's "
                   "examples), skipped with a note when there is none")
    p.add_argument("--no-startup", action="store_true", help="skip the FMU first-start "
                   "measurements (empty and warm caches)")
    p.add_argument("--step-horizon", type=float, metavar="S", help="simulated time of the "
                   "1e-3 s step costs (core, FMU, floor); default 1 s (0.02 s with --quick)")
    return p




def settings_from(args: argparse.Namespace):
    """The `gearpair.bench.Settings` of the command line options (a preset, then the
    overrides)."""
    from ..bench.settings import DEFAULT, FULL, QUICK

    s = QUICK if args.quick else FULL if args.full else DEFAULT
    if args.memory:
        s = replace(s, memory=True)
    if args.no_fmu:
        s = replace(s, fmu=False)
    if args.no_startup:
        s = replace(s, startup=False)
    if args.scenes is not None:
        if not Path(args.scenes).is_dir():
            raise ValueError(f"--scenes {args.scenes}: no such folder")
        s = replace(s, scenes_dir=args.scenes)
    if args.step_horizon is not None:
        if not (math.isfinite(args.step_horizon) and 0.0 < args.step_horizon <= 100.0):
            raise ValueError(f"--step-horizon = {args.step_horizon!r} must be in (0, 100] s")
        s = replace(s, step_horizon=float(args.step_horizon))
    return s


def run(args: argparse.Namespace) -> int:
    """``gearpair bench``: run, print the tables (or JSON), optionally draw the diagram."""
    s = settings_from(args)
    if args.plot:  # before minutes of measuring, not after them
        from ..writable import check_writable

        check_writable("--plot", args.plot)
        check_figure_format("--plot", args.plot)
    if s.fmu:  # the FMU is there (SceneError: how to build or pass it), before the minutes
        from ..scenes import SceneError
        from ..scenes.location import locate_fmu

        try:
            locate_fmu(args.fmu)
        except SceneError as exc:
            raise SceneError(f"{exc}; or --no-fmu to skip the FMU sections") from None
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    from .. import bench  # the package's `run`, which tests may replace
    from ..bench.report import jsonable, report

    result = bench.run(s, progress, fmu=args.fmu)
    if args.plot:
        try:
            from ..bench.plot import plot

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
