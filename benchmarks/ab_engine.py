"""Interleaved A/B of the fast engine's cost per step between two checkouts.

Each checkout runs in a process of its own virtual environment (``<root>/.venv``), the
variants alternating round by round, so that a load change on a shared machine hits both
alike. Every point is the best of ``--repeats`` CPU-time measurements after a settling run;
the table gives, per point, the median over the rounds and their range, and the ratio of
the medians. Compiled code comes from each checkout's cache (a first run compiles).

    .venv/bin/python benchmarks/ab_engine.py /path/to/main /path/to/branch --rounds 6

Run it on a quiet machine: a compile or a test run beside it shifts single rounds (the
range shows it).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

# (label, effects options, rtol, path, output step s, simulated s per repeat)
POINTS = [
    ("stick-slip rtol 1e-6 grid 1e-4", {}, 1e-6, "grid", 1e-4, 0.5),
    ("stick-slip rtol 1e-8 grid 1e-4", {}, 1e-8, "grid", 1e-4, 0.5),
    ("nominal rtol 1e-6 grid 1e-4", {"friction": "nominal"}, 1e-6, "grid", 1e-4, 0.5),
    ("no friction rtol 1e-6 grid 1e-4", {"friction": "off"}, 1e-6, "grid", 1e-4, 0.5),
    ("stick-slip rtol 1e-8 advance 1e-4", {}, 1e-8, "advance", 1e-4, 0.2),
    ("stick-slip rtol 1e-6 advance 1e-3", {}, 1e-6, "advance", 1e-3, 0.5),
    ("exact propagator advance 1e-4", {"friction": "off", "stiffness": "constant"}, 1e-8,
     "advance", 1e-4, 0.5),
    ("stick-slip rtol 1e-8 checked advance 1e-4", {}, 1e-8, "checked", 1e-4, 0.2),
]
TORQUE, SPEED = 3900.0, 100.0 * 2.0 * math.pi / 60.0  # N.m, rad/s (Table 1, 100 r/min)


def _time_point(eng, path: str, dt: float, span: float) -> float:
    """Microseconds of CPU per output step over ``span`` s after a start-up of 0.02 s."""
    import numpy as np

    eng.reset(torque=TORQUE, speed=SPEED)
    eng.advance(0.02, TORQUE, SPEED)  # past the start-up transient
    n = int(round(span / dt))
    t0 = eng.time
    c0 = time.process_time()
    if path == "grid":
        # `run` is the contract's name; a checkout from before it has `run_grid`
        run = eng.run if "run" in type(eng).__dict__ else eng.run_grid
        run(t0 + dt * np.arange(n + 1), TORQUE, SPEED)
    elif path == "advance":  # without the input check (what a caller that checked calls)
        for k in range(1, n + 1):
            eng.advance_values(t0 + k * dt, TORQUE, SPEED)
    else:  # `advance`: the input check and the step record, what Python callers get
        for k in range(1, n + 1):
            eng.advance(t0 + k * dt, TORQUE, SPEED)
    return (time.process_time() - c0) / n * 1e6


def _child(repeats: int) -> None:
    """Time every point in this process and print the figures as JSON."""
    from gearpair.effects import Effects
    from gearpair.fast import FastEngine

    out = {}
    for label, eff, rtol, path, dt, span in POINTS:
        eng = FastEngine(effects=Effects(**eff), rtol=rtol)
        _time_point(eng, path, dt, span)  # settle (and compile, on a first run)
        out[label] = min(_time_point(eng, path, dt, span) for _ in range(repeats))
    print(json.dumps(out))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("roots", nargs="*", help="checkouts to compare (each with a .venv)")
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        _child(a.repeats)
        return 0
    runs: dict[str, list[dict]] = {r: [] for r in a.roots}
    for k in range(a.rounds):
        for root in a.roots:
            py = os.path.join(root, ".venv", "bin", "python")
            res = subprocess.run([py, os.path.abspath(__file__), "--child", "--repeats",
                                  str(a.repeats)], capture_output=True, text=True, check=True,
                                 cwd=root)
            runs[root].append(json.loads(res.stdout.strip().splitlines()[-1]))
        print(f"round {k + 1}/{a.rounds} done, load {os.getloadavg()[0]:.1f}", file=sys.stderr)
    names = [os.path.basename(os.path.normpath(r)) for r in a.roots]
    print("| operating point (us per step) | " + " | ".join(names) + " | "
          + " | ".join(f"{n} / {names[0]}" for n in names[1:]) + " |")
    print("|---" * (2 * len(names)) + "|")
    for label, *_ in POINTS:
        med = [statistics.median(r[label] for r in runs[root]) for root in a.roots]
        cells = []
        for m, root in zip(med, a.roots, strict=True):
            vals = [r[label] for r in runs[root]]
            cells.append(f"{m:.2f} [{min(vals):.2f}-{max(vals):.2f}]")
        print(f"| {label} | " + " | ".join(cells) + " | "
              + " | ".join(f"{m / med[0]:.3f}" for m in med[1:]) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
