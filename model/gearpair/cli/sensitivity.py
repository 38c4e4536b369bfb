"""``gearpair sensitivity``: Sobol or Morris indices over parameter ranges, via the sweep store."""

from __future__ import annotations

import argparse
import json


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``gearpair sensitivity`` on an argparse subparsers object."""
    s = sub.add_parser(
        "sensitivity", help="Sobol (Saltelli) or Morris indices of sweep figures over "
        "parameter ranges (SALib), the points in a resumable sweep store",
        description="Example: gearpair sensitivity mu=0.01:0.05 torque=1000:4000 "
                    "speed_rpm=100:600 -n 256 --outputs stick_ratio,contact_loss_ratio. "
                    "The points and the indices go to one Zarr store (--store; the indices "
                    "as its group 'sensitivity').")
    s.add_argument("ranges", nargs="+", metavar="NAME=LO:HI|NAME=DIST:A:B...",
                   help="a sweepable parameter (speed_rpm in r/min, torque in N.m or a "
                   "GearParams field in SI units, e.g. mu) and its distribution in SALib's "
                   "terms: LO:HI (uniform), logunif:LO:HI, triang:LO:HI:PEAK (PEAK: the "
                   "mode's place as a fraction of the width, 0-1), norm:MEAN:SD, "
                   "truncnorm:LO:HI:MEAN:SD, lognorm:LN_MEAN:LN_SD (of the natural log), "
                   "weibull:SHAPE:SCALE[:LOC]; Morris: uniform only")
    s.add_argument("--method", default="sobol", choices=("sobol", "morris"),
                   help="Sobol indices with Saltelli sampling, or Morris elementary "
                   "effects (default sobol)")
    s.add_argument("-n", type=int, default=256, help="base sample size (Sobol: a power of "
                   "two, n (D + 2) points; Morris: trajectories, n (D + 1) points; "
                   "default 256)")
    s.add_argument("--outputs", default="stick_ratio,contact_loss_ratio",
                   help="comma-separated figures of a sweep point")
    s.add_argument("--second-order", action="store_true", help="Sobol S2 too")
    s.add_argument("--seed", type=int, default=1, help="seed of the sample (keep it to resume; "
                   "default 1)")
    s.add_argument("--store", default="sensitivity.zarr", metavar="PATH.zarr",
                   help="the sweep store of the sample points, and of the indices (its "
                   "group 'sensitivity': xr.open_zarr(PATH, group='sensitivity')); default "
                   "sensitivity.zarr")
    s.add_argument("--new-store", action="store_true", help="replace a store of another study")
    s.add_argument("--scheduler", help="'serial', or a dask scheduler address; default: a "
                   "local cluster")
    s.add_argument("--workers", type=int, help="local worker processes (default: one per "
                   "core)")
    from .sweep import add_settings_options

    add_settings_options(s)  # what every point holds, as in gearpair sweep
    s.add_argument("--plot", metavar="FILE.png", help="bar chart of the indices")
    s.add_argument("--json", action="store_true", help="print the indices as JSON")
    return s


def run(args) -> int:
    from ..sweep.sensitivity import parse_ranges, plot_indices, run_sensitivity
    from .sweep import settings_from_args

    ranges = parse_ranges(args.ranges)
    outputs = tuple(o.strip() for o in args.outputs.split(",") if o.strip())
    settings = settings_from_args(args)
    ds = run_sensitivity(ranges, args.method, args.n, outputs, settings, store=args.store,
                         second_order=args.second_order, seed=args.seed,
                         scheduler=args.scheduler, workers=args.workers,
                         new_store=args.new_store)
    if args.plot:
        plot_indices(ds, args.plot)
    if args.json:
        print(json.dumps({k: ds[k].values.tolist() for k in ds.data_vars}
                         | {"param": list(ds["param"].values),
                            "output": list(ds["output"].values)}))
    else:
        print(ds.drop_vars("distribution").to_dataframe().to_string())
        print("distributions: " + ", ".join(
            f"{p}={d}" for p, d in zip(ds["param"].values, ds["distribution"].values,
                                       strict=True)))
    return 0
