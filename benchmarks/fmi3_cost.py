"""GearPair3.fmu's step cost against GearPair.fmu's, and what early return adds (#35 item 4),
outside a whole `gearpair bench` run; with ``--wine`` also GearPair.fmu's win64 DLL under Wine
(#34 item 6).

The measurement is the bench's (`gearpair.bench.fmi3`, its host
``model/gearpair/bench/fmi3_bench_host.c``): both FMUs' binaries in one C process, the
variants stepping the same communication points round by round, back to back, at the FMUs'
default point (the paper's stick-slip scene: 3900 N.m, 100 r/min, mu 0.02, rtol 1e-8) on
1e-4 s steps. This script only runs more rounds of it, or longer ones, than the bench does,
and prints the bench's report of it.

    .venv/bin/python benchmarks/fmi3_cost.py [--fmu dist/GearPair.fmu] [--rounds 30] [--n 10000]
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
from dataclasses import replace
from pathlib import Path


def main(argv=None) -> int:
    from gearpair import bench
    from gearpair.bench import fmi3

    report = importlib.import_module("gearpair.bench.report")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu", default="dist/GearPair.fmu",
                    help="GearPair.fmu (GearPair3.fmu of the same build beside it)")
    ap.add_argument("--rounds", type=int, default=bench.DEFAULT.host_rounds,
                    help="rounds (each runs every variant once)")
    ap.add_argument("--n", type=int, default=bench.DEFAULT.host_n,
                    help="communication points of 1e-4 s per round")
    ap.add_argument("--wine", action="store_true",
                    help="also GearPair.fmu's win64 DLL under Wine against linux64")
    a = ap.parse_args(argv)
    fmu = Path(a.fmu)
    if not fmu.is_file():
        print(f"no {fmu}: run build_fmu.py first", file=sys.stderr)
        return 2
    s = replace(bench.DEFAULT, host_rounds=a.rounds, host_n=a.n)
    progress = lambda msg: print(msg, file=sys.stderr, flush=True)  # noqa: E731
    with tempfile.TemporaryDirectory(prefix="fmi3_cost_") as tmp:
        result = {"fmi3_host": fmi3.fmi3_measurements(s, fmu, Path(tmp) / "fmi3", progress)}
        if a.wine:
            result["wine_host"] = fmi3.wine_measurements(s, fmu, Path(tmp) / "wine", progress)
    print(f"load average {os.getloadavg()[0]:.1f}")
    print("\n".join(report._fmi3_host(result) + report._wine_host(result)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
