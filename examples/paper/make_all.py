"""Reproduce Figs. 4-18 of Xun, Dai & Wang (2023) as PNG files (Fig. 7, the flow chart of
the algorithm, is not a result; README "How the reference engine works" describes ours).

    python examples/paper/make_all.py                # full settings into build/paper/
    python examples/paper/make_all.py --quick        # short settings, serial (a smoke test)
    python examples/paper/make_all.py --scheduler tcp://HOST:8786   # sweeps on a cluster

The full run starts one local dask cluster for all sweeps (Figs. 15-18: 300 speeds for each
model, 41 friction coefficients, 32 torques) and reuses sweep files already in the output
folder when their values and settings match.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import parametric
import stiffness_modes
import time_response
from common import DEFAULT_OUT

from gearpair.sweep import local_cluster


def make_all(out: str | Path = DEFAULT_OUT, quick: bool = False, scheduler: str | None = None,
             workers: int | None = None) -> list[Path]:
    """Write every figure into ``out``; returns the paths."""
    paths = []
    for fn in (*stiffness_modes.FIGURES, *time_response.FIGURES):
        t = time.perf_counter()
        paths.append(fn(out, quick))
        print(f"{paths[-1]}  ({time.perf_counter() - t:.1f} s)", flush=True)

    def sweeps(addr):
        for fn in parametric.FIGURES:
            t = time.perf_counter()
            paths.append(fn(out, quick, addr, workers))
            print(f"{paths[-1]}  ({time.perf_counter() - t:.1f} s)", flush=True)

    if quick or scheduler:
        sweeps(scheduler)
    else:
        with local_cluster(workers) as addr:
            sweeps(addr)
    return paths


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--scheduler", default=None)
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args(argv)
    make_all(a.out, a.quick, a.scheduler, a.workers)


if __name__ == "__main__":
    main()
