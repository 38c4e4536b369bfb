"""``gearpair sweep``: the parser and the run live in `gearpair.sweep` for now (its own
package is being split out); this module is the subcommand's place in the command line."""

from __future__ import annotations

import argparse


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``sweep`` on the ``gearpair`` subparsers object."""
    from ..sweep import add_parser as add_sweep_parser  # argparse only; dask loads on use

    return add_sweep_parser(sub)


def run(args) -> int:
    from ..sweep import main as sweep_main

    return sweep_main(args)
