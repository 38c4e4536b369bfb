"""`gearpair` command line: thin wrappers over the core.

gearpair modes [--json]
gearpair simulate [--json] [--out run.csv] [--t-end S] [--speed-rpm N] [--torque NM] ...
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from .effects import Effects, StiffnessSpec
from .equations import Model
from .modal import SLIP_NAMES, modes
from .params import RPM, GearParams, OperatingPoint


def _modes(args) -> int:
    model = Model.build(GearParams(), Effects(stiffness="constant"))
    out = {}
    for which in ("slip", "stick"):
        f, shapes = modes(model, which)
        out[which] = {
            "frequencies_hz": [round(float(x), 6) for x in f],
            "coordinates": list(SLIP_NAMES),
            "mode_shapes": [[round(float(v), 6) for v in shapes[:, i]] for i in range(len(f))],
        }
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    for which, d in out.items():
        print(f"{which} model: natural frequencies (Hz) and mode shapes (largest component 1)")
        print("  mode  f (Hz)     " + "  ".join(f"{n:>7s}" for n in SLIP_NAMES))
        for i, f in enumerate(d["frequencies_hz"]):
            row = "  ".join(f"{v:7.3f}" for v in d["mode_shapes"][i])
            print(f"  {i + 1:4d}  {f:9.3f}  {row}")
    return 0


def _effects(args) -> Effects:
    return Effects(
        stiffness=StiffnessSpec(kind=args.stiffness), separation=not args.no_separation,
        friction=args.friction, sliding=args.sliding, stick_tie=args.stick_tie,
    )


def _simulate(args) -> int:
    from .results import simulate

    op = OperatingPoint(torque=args.torque, speed=args.speed_rpm * RPM)
    params = GearParams(mu=args.mu)
    traj = simulate(params, _effects(args), t_end=args.t_end, torque=op.torque,
                    speed=op.speed, dt=args.dt, engine=args.engine, rtol=args.rtol)
    t_from = args.t_end * args.steady_from
    summ = traj.summary(t_from)
    summ["engine"] = args.engine
    summ["torque_nm"] = op.torque
    summ["speed_rpm"] = args.speed_rpm
    summ["events"] = int(np.sum(traj["n_events"]))
    if args.out:
        traj.to_csv(args.out)
        summ["out"] = args.out
    if args.json:
        print(json.dumps(summ, indent=2))
        return 0
    f = summ["mesh_force_n"]
    print(f"gear pair at {args.speed_rpm:g} r/min, {op.torque:g} N.m, engine {args.engine}, "
          f"steady window {t_from:g}-{args.t_end:g} s")
    print(f"  stick ratio          {summ['stick_ratio']:.4f}")
    print(f"  contact-loss ratio   {summ['contact_loss_ratio']:.4f}")
    print(f"  mesh force (kN)      min {f['min'] / 1e3:.2f}  mean {f['mean'] / 1e3:.2f}  "
          f"max {f['max'] / 1e3:.2f}")
    if args.out:
        print(f"  written {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="gearpair", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("modes", help="natural frequencies and mode shapes (Figs. 5-6)")
    m.add_argument("--json", action="store_true")
    s = sub.add_parser("simulate", help="run the default operating point and summarize")
    s.add_argument("--json", action="store_true")
    s.add_argument("--out", help="write the trajectory as CSV")
    s.add_argument("--t-end", type=float, default=0.2, help="simulated time (s)")
    s.add_argument("--dt", type=float, default=1e-4, help="output interval (s)")
    s.add_argument("--steady-from", type=float, default=0.5,
                   help="start of the steady window as a fraction of t-end")
    s.add_argument("--torque", type=float, default=OperatingPoint().torque, help="N.m")
    s.add_argument("--speed-rpm", type=float, default=OperatingPoint().speed / RPM)
    s.add_argument("--mu", type=float, default=GearParams().mu)
    s.add_argument("--engine", default="reference")
    s.add_argument("--rtol", type=float, default=1e-7)
    s.add_argument("--stiffness", default="potential_energy")
    s.add_argument("--friction", default="stick_slip")
    s.add_argument("--sliding", default="paper")
    s.add_argument("--stick-tie", default="exact")
    s.add_argument("--no-separation", action="store_true")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return {"modes": _modes, "simulate": _simulate}[args.cmd](args)
    except ValueError as exc:
        print(f"gearpair: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
