"""Seeded random scan for missed contact events (issue 38); its result is in docs/limits.md.

    .venv/bin/python scripts/contact_scan.py --runs 200 --seed 1 [--reference 10]

Draws runs of ``--t-end`` seconds (speeds up to 10,000 r/min, torques from 50 N.m, every
stiffness and friction law, with and without backlash, torque reversals by a step or a slow
oscillation through zero, zero and small damping), runs each with the fast engine and checks
every output sample: the contact state agrees with the geometry and the DTE stays within its
bound (`tests/test_contact_events.py` holds the check and a 10-run version of this scan).
A run may also stop with an unbounded response (`RunFailure`), which is counted; a missed
event, any other error or a sample that disagrees is listed. ``--reference K`` re-runs the
first K completed runs with the scipy reference engine (slow: minutes per run at high
speed) and compares the contact-loss and back-contact ratios.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def random_case(rng: np.random.Generator):
    """(GearParams, Effects, torque schedule, speed in rad/s) of one scan run."""
    from gearpair import RPM, Effects, GearParams
    from gearpair.inputs import Function, Step

    stiffness = str(rng.choice(["potential_energy", "rectangular", "constant"]))
    friction = str(rng.choice(["off", "nominal", "regularized", "stick_slip"]))
    backlash = None if rng.random() < 0.3 else float(10 ** rng.uniform(-5, -3))
    damping = float(rng.choice([0.0, 0.01, 0.1]))
    speed = float(10 ** rng.uniform(2, 4)) * RPM
    torque = float(10 ** rng.uniform(math.log10(50), 4))
    kind = rng.integers(3)
    if kind == 1 and backlash is not None:
        T = Step(torque, -torque, float(rng.uniform(0.2, 0.8)))
    elif kind == 2 and backlash is not None:
        f = float(rng.uniform(1, 5))
        T = Function(lambda t, a=torque, f=f: a * math.cos(2 * math.pi * f * t))
    else:
        T = torque
    params = GearParams() if damping == 0.1 else GearParams(damping_ratio=damping)
    return params, Effects(stiffness=stiffness, friction=friction, backlash=backlash), T, speed


def describe(params, effects, T, speed) -> str:
    from gearpair import RPM

    t = T if isinstance(T, float) else type(T).__name__ + (
        f"({T.before:g}->{T.after:g} at {T.at:.3g} s)" if hasattr(T, "at") else "(cos)")
    return (f"{effects.stiffness.kind} {effects.friction} backlash={effects.backlash} "
            f"damping={params.damping_ratio:g} torque={t} speed={speed / RPM:.0f} r/min")


def checker():
    """`assert_state_matches_geometry` of the test module (one check, written once)."""
    spec = importlib.util.spec_from_file_location("contact_events",
                                                  ROOT / "tests" / "test_contact_events.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.assert_state_matches_geometry


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--t-end", type=float, default=1.0)
    ap.add_argument("--dt", type=float, default=1e-3, help="output step (s)")
    ap.add_argument("--reference", type=int, default=0)
    a = ap.parse_args(argv)
    from gearpair.engine import RunFailure
    from gearpair.results import simulate

    check = checker()
    rng = np.random.default_rng(a.seed)
    counts = {"ok": 0, "unbounded": 0, "missed": 0, "error": 0, "disagrees": 0}
    done, t0 = [], time.perf_counter()
    for i in range(a.runs):
        case = random_case(rng)
        p, fx, T, W = case
        try:
            tr = simulate(p, fx, t_end=a.t_end, torque=T, speed=W, dt=a.dt)
        except RunFailure as e:
            kind = "unbounded" if "unbounded" in str(e) else "missed"
            counts[kind] += 1
            print(f"{i:4d} {kind}: {describe(*case)}: {e}"[:300])
            continue
        except Exception as e:  # noqa: BLE001 - every failure is counted and shown
            counts["error"] += 1
            print(f"{i:4d} error: {describe(*case)}: {type(e).__name__}: {e}"[:300])
            continue
        try:
            check(tr, p, fx)
        except AssertionError as e:
            counts["disagrees"] += 1
            print(f"{i:4d} disagrees: {describe(*case)}: {e}"[:300])
            continue
        counts["ok"] += 1
        done.append((case, tr.ratios()))
    print(f"{a.runs} runs of {a.t_end:g} s (seed {a.seed}) in "
          f"{time.perf_counter() - t0:.0f} s: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    worst = 0.0
    for case, fast in done[:a.reference]:
        p, fx, T, W = case
        ref = simulate(p, fx, t_end=a.t_end, torque=T, speed=W, dt=a.dt,
                       engine="reference").ratios()
        diff = max(abs(fast[k] - ref[k]) for k in ("contact_loss_ratio", "back_contact_ratio"))
        worst = max(worst, diff)
        print(f"reference: {describe(*case)}: ratios differ by {diff:.2e}")
    if a.reference:
        print(f"reference engine on {min(a.reference, len(done))} runs: largest ratio "
              f"difference {worst:.2e}")
    return 1 if counts["missed"] or counts["error"] or counts["disagrees"] else 0


if __name__ == "__main__":
    sys.exit(main())
