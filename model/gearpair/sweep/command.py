"""``gearpair sweep``: arguments and the command."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ..params import RTOL_MIN
from .run import run_sweep
from .settings import SweepSettings


# -- command line -----------------------------------------------------------------------------
def parse_values(text: str) -> list[float]:
    """``"a,b,c"`` or ``"start:stop:num"`` (num evenly spaced values, both ends included)."""
    text = text.strip()
    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise ValueError(f"values {text!r}: use start:stop:num")
        try:
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise ValueError(f"values {text!r}: use start:stop:num with numbers start, stop "
                             "and a whole number num, e.g. 2:600:300") from None
        if n < 1:
            raise ValueError(f"values {text!r}: num must be >= 1")
        return [float(v) for v in np.linspace(a, b, n)]
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"values {text!r}: numbers separated by commas expected") from None


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``gearpair sweep`` on an argparse subparsers object."""
    d = SweepSettings()
    s = sub.add_parser(
        "sweep", help="stick/contact-loss ratios and bifurcation data over a parameter (dask)",
        description="Sweep one parameter; writes PREFIX.csv, PREFIX_poincare.csv, PREFIX.json "
                    "and PREFIX.png. Example: gearpair sweep speed_rpm 5:600:300 --out speed")
    from ..effects import FRICTION_LAWS, SLIDING_VARIANTS, STICK_TIES, STIFFNESS_KINDS
    from ..params import RTOL_MAX

    s.add_argument("param", help="what to sweep: speed_rpm (r/min), torque (N.m) or a "
                   "GearParams field in SI units (e.g. mu, kb1, module)")
    s.add_argument("values", help="a,b,c or start:stop:num (num evenly spaced values, both "
                   "ends included), in the unit of PARAM")
    s.add_argument("--out", default="sweep", metavar="PREFIX", help="output prefix: writes "
                   "PREFIX.csv, PREFIX_poincare.csv, PREFIX.json, PREFIX.png (its folder is "
                   "created; checked for writing before the run); default sweep")
    s.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running dask scheduler (tcp://host:port); 'serial' runs "
                   "in this process; default: a local cluster of --workers processes")
    s.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes; default: the number of CPU cores")
    s.add_argument("--retries", type=int, default=1, metavar="N",
                   help="reruns of a failed point, each with a ten times tighter rtol; "
                   "default 1")
    s.add_argument("--torque", type=float, default=d.torque, metavar="NM",
                   help=f"driving torque on gear 1 when not swept (N.m); default {d.torque:g}")
    s.add_argument("--speed-rpm", type=float, default=d.speed_rpm, metavar="RPM",
                   help=f"speed of gear 1 when not swept (r/min); default {d.speed_rpm:g}")
    s.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="change a GearParams field (SI), e.g. --set mu=0.03; repeatable; "
                   "default: Table 1")
    s.add_argument("--friction", default=d.friction, choices=FRICTION_LAWS,
                   help="friction law: stick_slip (the paper's model), nominal (the slip "
                   f"model), regularized or off; default {d.friction}")
    s.add_argument("--stick-tie", default=d.stick_tie, choices=STICK_TIES,
                   help=f"how stuck teeth move together: exact (v = 0) or paper (Eq. 19); "
                   f"default {d.stick_tie}")
    s.add_argument("--sliding", default=d.sliding, choices=SLIDING_VARIANTS,
                   help=f"sliding velocity: paper (Eq. 12) or full; default {d.sliding}")
    s.add_argument("--stiffness", default=d.stiffness,
                   choices=[k for k in STIFFNESS_KINDS if k != "table"],
                   help=f"mesh stiffness law; default {d.stiffness}")
    s.add_argument("--no-separation", action="store_true",
                   help="teeth never separate (a linear mesh spring); default: they do")
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
    s.add_argument("--no-plot", action="store_true", help="do not draw PREFIX.png; default: "
                   "draw it (needs matplotlib)")
    s.add_argument("--quiet", action="store_true", help="no progress line on stderr")
    return s


def settings_from_args(args) -> SweepSettings:
    over = []
    for item in args.set:
        k, sep, v = item.partition("=")
        if not sep:
            raise ValueError(f"--set {item!r}: use NAME=VALUE")
        over.append((k.strip(), float(v)))
    return SweepSettings(
        torque=args.torque, speed_rpm=args.speed_rpm, params=tuple(over),
        friction=args.friction, stick_tie=args.stick_tie, sliding=args.sliding,
        stiffness=args.stiffness, separation=not args.no_separation, rtol=args.rtol,
        steps_per_period=args.steps_per_period, transient_periods=args.transient_periods,
        transient_time=args.transient_time, kept_periods=args.kept_periods,
        max_time=args.max_time)


def main(args) -> int:
    """``gearpair sweep``: run, write the files, report the throughput; exit status 1 when a
    point failed or was invalid (it is in the CSV with its error)."""
    settings = settings_from_args(args)
    # Check names and the held values here, so a typo fails before a cluster starts.
    settings.inputs("speed_rpm", settings.speed_rpm)
    values = parse_values(args.values)
    # the heaviest tooth load of the sweep, once, before the run (a GearDataWarning line)
    from ..geometry import unit_load, warn_implausible_load

    points = []
    for v in values:
        try:
            points.append(settings.inputs(args.param, v))
        except ValueError:  # refused at its run: an `invalid` record, not an error here
            pass
    if points:
        p, _, torque, _ = max(points, key=lambda pt: unit_load(pt[0], pt[2]))
        warn_implausible_load(p, torque)
    # every output file before the run, not after it (`SweepResult.write` names them)
    from ..writable import check_writable

    prefix = Path(args.out)
    names = [prefix.with_suffix(".csv"), Path(f"{prefix}_poincare.csv"),
             prefix.with_suffix(".json")] + ([] if args.no_plot else [prefix.with_suffix(".png")])
    for name in names:
        check_writable("--out", name, shown=args.out)
    res = run_sweep(args.param, values, settings, scheduler=args.scheduler,
                    workers=args.workers, retries=args.retries, progress=not args.quiet)
    files = res.write(args.out, plot=not args.no_plot)
    print(res.report(), file=sys.stderr)
    print(json.dumps({"files": files, **{k: v for k, v in res.summary().items()
                                         if k != "settings"}}, indent=2, default=str))
    return 1 if res.failed or res.invalid else 0

