"""`gearpair` command line: thin wrappers over the core.

gearpair modes [--json]
gearpair simulate SCENE.toml [--engine fast|fmu|reference] [--out run.csv] [--plot run.png]
                  [--json] [--t-end S]
gearpair simulate [--json] [--out run.csv] [--t-end S] [--speed-rpm N] [--torque NM] ...
"""

from __future__ import annotations

import argparse
import json
import sys
import time

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


# Flags that describe the run itself: without a scene file only (a scene says all of it).
_RUN_FLAGS = {"dt": 1e-4, "steady_from": 0.5, "torque": OperatingPoint().torque,
              "speed_rpm": OperatingPoint().speed / RPM, "mu": GearParams().mu, "rtol": 1e-7,
              "stiffness": "potential_energy", "friction": "stick_slip", "sliding": "paper",
              "stick_tie": "exact", "no_separation": False}


def _scene_from_flags(args):
    """The flag-based run as a scene: constant inputs, Table 1 data with ``--mu``."""
    from .scenes import Constant, Inputs, OutputSpec, Scene, Solver

    for k, v in _RUN_FLAGS.items():
        if getattr(args, k) is None:
            setattr(args, k, v)
    t_end = 0.2 if args.t_end is None else args.t_end
    if not (t_end > 0 and args.dt > 0):
        raise ValueError(f"--t-end = {t_end!r} and --dt = {args.dt!r} must be > 0 s")
    op = OperatingPoint(torque=args.torque, speed=args.speed_rpm * RPM)
    scene = Scene(
        name="command line", params=GearParams(mu=args.mu), effects=_effects(args),
        inputs=Inputs(torque=Constant(op.torque), speed=Constant(op.speed)),
        solver=Solver(engine=args.engine or "fast", rtol=args.rtol),
        outputs=OutputSpec(interval=args.dt), t_end=t_end)
    # the window as a fraction of t_end, kept even past the end (then the summary says so)
    return scene, t_end * args.steady_from, {"torque_nm": op.torque, "speed_rpm": args.speed_rpm}


def _scene_from_file(args):
    from .scenes import load_scene

    given = [k for k in _RUN_FLAGS if getattr(args, k) not in (None, False)]
    if given:
        flags = ", ".join("--" + k.replace("_", "-") for k in given)
        raise ValueError(f"{flags}: set this in the scene file; with a scene only --engine, "
                         "--t-end, --out, --plot and --json apply")
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(args.scene)
    for w in caught:  # one line each, before the run (e.g. an input-CSV column no input uses)
        print(f"gearpair: warning: {w.message}", file=sys.stderr)
    if args.t_end is not None:
        scene = scene.with_t_end(args.t_end)
    return scene, scene.t_from, {"scene_file": str(args.scene)}


def _check_outputs(args) -> None:
    """Refuse what would fail only after the run: create the folders of --out and --plot
    (as ``sweep --out`` does) and check the figure format."""
    from pathlib import Path

    for flag, path in (("--out", args.out), ("--plot", args.plot)):
        if not path:
            continue
        p = Path(path)
        if p.is_dir():
            raise ValueError(f"{flag} {path}: is a folder; give a file name")
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"{flag} {path}: cannot create its folder ({exc.strerror})") \
                from None
    if args.plot:
        try:
            from matplotlib.backend_bases import FigureCanvasBase
        except ImportError:  # reported by Trajectory.plot after the run
            return
        kinds = FigureCanvasBase.get_supported_filetypes()
        suffix = Path(args.plot).suffix.lstrip(".").lower()
        if suffix not in kinds:
            raise ValueError(f"--plot {args.plot}: unknown figure format {suffix!r}; allowed "
                             + ", ".join(sorted(kinds)))


def _simulate(args) -> int:
    scene, t_from, extra = (_scene_from_file if args.scene else _scene_from_flags)(args)
    engine = args.engine or scene.solver.engine
    _check_outputs(args)
    wall0 = time.perf_counter()
    try:
        traj = scene.run(engine)
    except (RuntimeError, ArithmeticError, ImportError) as exc:
        # a failed run or a missing extra, not bad input
        print(f"gearpair: error: {exc}", file=sys.stderr)
        return 1
    # run time apart from start-up (building the engine, loading its compiled code): the
    # FMU's run includes its instantiation, so its start-up is not known apart
    startup = traj.meta.get("startup_s")
    wall = traj.meta.get("wall_time_s", time.perf_counter() - wall0)
    summ = {"scene": scene.name, "engine": engine, "t_end": scene.t_end, **extra,
            **traj.summary(t_from)}
    summ["events"] = int(np.sum(traj["n_events"]))
    summ["wall_time_s"] = wall
    summ["wall_time_per_simulated_s"] = wall / scene.t_end
    summ["startup_s"] = startup
    if args.out:
        from .scenes import OUTPUT_NAMES

        names = scene.outputs.names if args.scene else None
        if names == OUTPUT_NAMES:  # the default: what this engine recorded (the FMU has less)
            names = [n for n in names if n in traj.data]
        traj.to_csv(args.out, names)
        summ["out"] = args.out
    if args.plot:
        try:
            traj.plot(args.plot, title=f"{scene.name} ({engine} engine)")
        except ImportError as exc:
            print(f"gearpair: error: {exc}", file=sys.stderr)
            return 1
        summ["plot"] = args.plot
    if args.json:
        print(json.dumps(summ, indent=2))
        return 0
    f, d = summ["mesh_force_n"], summ["dte_m_sampled"]
    if args.scene:
        print(f"scene {scene.name} ({args.scene}), engine {engine}, 0-{scene.t_end:g} s, "
              f"steady window {t_from:g}-{scene.t_end:g} s")
    else:
        print(f"gear pair at {args.speed_rpm:g} r/min, {extra['torque_nm']:g} N.m, engine "
              f"{engine}, steady window {t_from:g}-{scene.t_end:g} s")
    print(f"  stick ratio          {summ['stick_ratio']:.4f}")
    print(f"  contact-loss ratio   {summ['contact_loss_ratio']:.4f}")
    if "back_contact_ratio" in summ:
        print(f"  back-contact ratio   {summ['back_contact_ratio']:.4f}")
    mean = f"mean {f['mean'] / 1e3:.2f}" if "mean" in f else \
        f"mean of the samples {f['mean_sampled'] / 1e3:.2f}"
    print(f"  mesh force (kN)      min {f['min'] / 1e3:.2f}  {mean}  max {f['max'] / 1e3:.2f}")
    print(f"  DTE (um, samples)    mean {d['mean'] * 1e6:.3f}  peak-to-peak "
          f"{d['peak_to_peak'] * 1e6:.3f}")
    start = "" if startup is None else f"; start-up {startup:.2f} s apart"
    print(f"  wall time            {wall:.2f} s ({wall / scene.t_end:.3f} s per simulated s"
          f"{start})")
    for key in ("out", "plot"):
        if key in summ:
            print(f"  written {summ[key]}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="gearpair", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("modes", help="natural frequencies and mode shapes (Figs. 5-6)")
    m.add_argument("--json", action="store_true")
    s = sub.add_parser("simulate", help="run a scene file (or one operating point given by "
                       "flags) and summarize")
    s.add_argument("scene", nargs="?", help="scene file (TOML, docs/scenes.md); without it "
                   "the flags below describe the run")
    s.add_argument("--json", action="store_true", help="print the summary as JSON")
    s.add_argument("--out", help="write the trajectory as CSV (units in the header)")
    s.add_argument("--plot", help="draw DTE, mesh force, friction and contact state (e.g. "
                   "run.png; needs matplotlib)")
    s.add_argument("--engine", choices=("fast", "reference", "fmu"),
                   help="default: the scene's [solver] engine; fast without a scene")
    s.add_argument("--t-end", type=float, help="simulated time (s); overrides the scene's "
                   "(default 0.2 without a scene)")
    d = _RUN_FLAGS
    run = s.add_argument_group("run without a scene file")
    run.add_argument("--dt", type=float, help=f"output interval (s), default {d['dt']:g}")
    run.add_argument("--steady-from", type=float, help="start of the steady window as a "
                     f"fraction of t-end, default {d['steady_from']:g}")
    run.add_argument("--torque", type=float, help=f"N.m, default {d['torque']:g}")
    run.add_argument("--speed-rpm", type=float, help=f"default {d['speed_rpm']:g}")
    run.add_argument("--mu", type=float, help=f"default {d['mu']:g}")
    run.add_argument("--rtol", type=float, help=f"default {d['rtol']:g}")
    run.add_argument("--stiffness", help=f"default {d['stiffness']}")
    run.add_argument("--friction", help=f"default {d['friction']}")
    run.add_argument("--sliding", help=f"default {d['sliding']}")
    run.add_argument("--stick-tie", help=f"default {d['stick_tie']}")
    run.add_argument("--no-separation", action="store_true", default=None)
    from .sweep import add_parser as add_sweep_parser  # argparse only; dask loads on use

    add_sweep_parser(sub)
    from .bench import add_parser as add_bench_parser  # argparse only; runs load on use

    add_bench_parser(sub)
    return ap


def _sweep(args) -> int:
    from .sweep import main as sweep_main

    return sweep_main(args)


def _bench(args) -> int:
    from .bench import main as bench_main

    return bench_main(args)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return {"modes": _modes, "simulate": _simulate, "sweep": _sweep,
                "bench": _bench}[args.cmd](args)
    except ValueError as exc:
        print(f"gearpair: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a path the user gave: missing, unreadable, unwritable
        where = f": {exc.filename}" if exc.filename else ""
        print(f"gearpair: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
