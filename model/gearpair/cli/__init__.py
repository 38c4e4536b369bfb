"""`gearpair` command line: thin wrappers over the core, one module per subcommand.

gearpair modes [SCENE.toml] [--set NAME=VALUE ...] [--bore-ratio R] [--first-mode-hz F] [--json]
gearpair simulate SCENE.toml [--engine fast|fmu|reference] [--out run.csv] [--plot run.png]
                  [--json] [--t-end S] [--set NAME=VALUE ...]
gearpair simulate [--json] [--out run.csv] [--t-end S] [--speed-rpm N] [--torque NM] ...
gearpair sweep PARAM VALUES | NAME=VALUES ... [--store S.zarr] [...]    gearpair bench [...]

Each subcommand module (`modes`, `simulate`, `sweep`, `bench`) has ``add_parser(sub)`` and
``run(args)``; `common` holds the options they share. Building the parser imports no
engine, no benchmark and no dask: a subcommand imports what it runs when it runs.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings

from .. import __version__
from . import bench, modes, sensitivity, simulate, sweep
from .common import warning_line

__all__ = ["COMMANDS", "build_parser", "main"]

COMMANDS = {"modes": modes, "simulate": simulate, "sweep": sweep,
            "sensitivity": sensitivity, "bench": bench}


def build_parser() -> argparse.ArgumentParser:
    """The ``gearpair`` parser with every subcommand of `COMMANDS`."""
    ap = argparse.ArgumentParser(
        prog="gearpair", description="Spur gear pair dynamics with stick-slip (Xun, Dai & "
        "Wang 2023): natural frequencies, simulation, parameter sweeps and benchmarks.",
        epilog="'gearpair COMMAND -h' lists the options of a command. Units are SI unless "
        "the option says otherwise.")
    ap.add_argument("--version", action="version", version=f"%(prog)s {__version__}",
                    help="print the version and exit")
    sub = ap.add_subparsers(dest="cmd", metavar="COMMAND")
    for command in COMMANDS.values():
        command.add_parser(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    """The console script ``gearpair``: exit status 0, 1 for a failed run, 2 for bad input
    (one line on stderr)."""
    ap = build_parser()
    args = ap.parse_args(argv)
    if args.cmd is None:  # bare `gearpair`: the help, and argparse's status for a usage error
        ap.print_help()
        return 2
    # a first run on a machine compiles the fast engine: say so on stderr (gearpair.jitcache)
    os.environ.setdefault("GEARPAIR_COMPILE_NOTICE", "1")
    with warnings.catch_warnings():
        warnings.showwarning = warning_line
        try:
            return COMMANDS[args.cmd].run(args)
        except ValueError as exc:
            print(f"gearpair: error: {exc}", file=sys.stderr)
            return 2
        except OSError as exc:  # a path the user gave: missing, unreadable, unwritable
            where = f": {exc.filename}" if exc.filename else ""
            print(f"gearpair: error: {exc.strerror or exc}{where}", file=sys.stderr)
            return 2
