"""``gearpair simulate``: run a scene file, or one operating point given by flags, and
summarize it (ratios of Eqs. 26-27, mesh force, DTE; CSV and figure on request)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace

import numpy as np

from ..params import RPM, RTOL_MAX, RTOL_MIN, GearParams, OperatingPoint
from .common import (
    add_effect_options,
    add_gear_options,
    changed,
    check_figure_format,
    effect_flags,
    effects_from_args,
    gear_from_args,
    parse_set,
)


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``simulate`` on the ``gearpair`` subparsers object."""
    s = sub.add_parser("simulate", help="run a scene file (or one operating point given by "
                       "flags) and summarize",
                       description="Simulate a scene file, or one operating point given by "
                       "the flags, and print the stick and contact-loss ratios (Eqs. 26-27), "
                       "mesh force and DTE over the steady window.")
    s.add_argument("scene", nargs="?", help="scene file (TOML, docs/scenes.md); without it "
                   "the flags below describe the run")
    s.add_argument("--json", action="store_true", help="print the summary as JSON")
    s.add_argument("--out", metavar="FILE.csv", help="write the trajectory as CSV: header "
                   "of plain output names (time, dte, ...; SI units, listed in "
                   "docs/scenes.md), readable by fmpy --input-file and [inputs.csv]")
    s.add_argument("--plot", metavar="FILE", help="draw DTE, mesh force, friction and "
                   "contact state (format from the suffix, e.g. run.png; needs matplotlib)")
    s.add_argument("--engine", choices=("fast", "reference", "fmu"),
                   help="integrator: fast (numba), reference (scipy) or fmu (the built FMU "
                   "through fmpy); default: the scene's [solver] engine, fast without "
                   "a scene")
    s.add_argument("--fmu", metavar="PATH", help="the FMU of --engine fmu; default "
                   "$GEARPAIR_FMU, else dist/GearPair.fmu of the current folder (python "
                   "build_fmu.py writes it there), rebuilt when stale")
    s.add_argument("--t-end", type=float, metavar="S", help="simulated time (s), overrides "
                   "the scene's; default 0.2 without a scene")
    d = _RUN_FLAGS
    run = s.add_argument_group("run without a scene file")
    run.add_argument("--dt", type=float, metavar="S", help=f"output interval and "
                     f"communication step (s); default {d['dt']:g}")
    run.add_argument("--steady-from", type=float, metavar="FRACTION", help="start of the "
                     f"steady window as a fraction of --t-end; default {d['steady_from']:g}")
    run.add_argument("--torque", type=float, metavar="NM", help="driving torque on gear 1 "
                     f"(N.m); default {d['torque']:g}")
    run.add_argument("--speed-rpm", type=float, metavar="RPM", help="speed of gear 1 (r/min); "
                     f"default {d['speed_rpm']:g}")
    run.add_argument("--mu", type=float, help="coefficient of friction, [0, 1]; default "
                     f"{d['mu']:g}")
    run.add_argument("--rtol", type=float, help="relative tolerance of the integrator, "
                     f"[{RTOL_MIN:g}, {RTOL_MAX:g}]; default {d['rtol']:g}")
    add_effect_options(run)
    add_gear_options(s)
    return s


# Flags that describe the run itself: without a scene file only (a scene says all of it).
_RUN_FLAGS = {"dt": 1e-4, "steady_from": 0.5, "torque": OperatingPoint().torque,
              "speed_rpm": OperatingPoint().speed / RPM, "mu": GearParams().mu, "rtol": 1e-7,
              **effect_flags()}


def _scene_from_flags(args):
    """The flag-based run as a scene: constant inputs, Table 1 data with ``--mu`` and
    ``--set``."""
    from ..inputs import Constant
    from ..scenes import Inputs, OutputSpec, Scene, Solver

    if args.mu is not None and "mu" in parse_set(args.set):
        raise ValueError("give --mu or --set mu=..., not both")
    for k, v in _RUN_FLAGS.items():
        if getattr(args, k) is None:
            setattr(args, k, v)
    t_end = 0.2 if args.t_end is None else args.t_end
    if not (t_end > 0 and args.dt > 0):
        raise ValueError(f"--t-end = {t_end!r} and --dt = {args.dt!r} must be > 0 s")
    op = OperatingPoint(torque=args.torque, speed=args.speed_rpm * RPM)
    effects = effects_from_args(args)
    scene = Scene(
        name="command line", params=gear_from_args(args, GearParams(mu=args.mu), effects),
        effects=effects,
        inputs=Inputs(torque=Constant(op.torque), speed=Constant(op.speed)),
        solver=Solver(engine=args.engine or "fast", rtol=args.rtol),
        outputs=OutputSpec(interval=args.dt), t_end=t_end)
    # the window as a fraction of t_end, kept even past the end (then the summary says so)
    return scene, t_end * args.steady_from, {"torque_nm": op.torque, "speed_rpm": args.speed_rpm}


def _scene_from_file(args):
    from ..scenes import load_scene

    given = [k for k in _RUN_FLAGS if getattr(args, k) not in (None, False)]
    if given:
        flags = ", ".join("--" + k.replace("_", "-") for k in given)
        raise ValueError(f"{flags}: set this in the scene file; with a scene only --engine, "
                         "--fmu, --t-end, --out, --plot and --json apply")
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(args.scene)
    for w in caught:  # one line each, before the run (e.g. an input-CSV column no input uses)
        print(f"gearpair: warning: {w.message}", file=sys.stderr)
    if args.set or args.bore_ratio is not None or args.first_mode_hz is not None:
        scene = replace(scene, params=gear_from_args(args, scene.params, scene.effects))
    if args.t_end is not None:
        scene = scene.with_t_end(args.t_end)
    return scene, scene.t_from, {"scene_file": str(args.scene)}




def _check_outputs(args) -> None:
    """Refuse what would fail only after the run: --out and --plot must be writable files
    (their folders are created, as ``sweep --out`` does) and the figure format known."""
    from ..writable import check_writable

    for flag, path in (("--out", args.out), ("--plot", args.plot)):
        if path is not None:
            check_writable(flag, path)
    if args.plot:
        check_figure_format("--plot", args.plot)



def _schedule_text(f, unit: str, scale: float = 1.0) -> str:
    """An input schedule in a few words (constant value, ramp, step, CSV series)."""
    from ..inputs import Ramp, Series, Step

    if isinstance(f, Ramp):
        return f"{f.start * scale:g}->{f.end * scale:g} {unit} ramp"
    if isinstance(f, Step):
        return f"{f.before * scale:g}->{f.after * scale:g} {unit} step at {f.at:g} s"
    if isinstance(f, Series):
        return f"{unit} from {f.source or 'CSV'}"
    return f"{f(0.0) * scale:g} {unit}"


def plot_title(scene, engine: str) -> str:
    """The figure title: scene, operating point (speed, torque, mu) and effects, engine."""
    fx = scene.effects
    eff = [f"friction {fx.friction}", f"stiffness {fx.stiffness.kind}"]
    if not fx.separation:
        eff.append("no separation")
    if fx.backlash is not None:
        eff.append(f"backlash {fx.backlash * 1e6:g} um")
    if fx.dof != "full":
        eff.append(fx.dof)
    if fx.friction in ("nominal", "regularized", "stick_slip"):
        eff.append(f"sliding {fx.sliding}")
    if fx.friction == "stick_slip":
        eff.append(f"tie {fx.stick_tie}")
    gear = "" if not changed(scene.params).keys() - {"mu"} else ", own gear data"
    return (f"{scene.name}: {_schedule_text(scene.inputs.speed, 'r/min', 1 / RPM)}, "
            f"{_schedule_text(scene.inputs.torque, 'N.m')}, mu {scene.params.mu:g}{gear}\n"
            f"{', '.join(eff)}; {engine} engine")


def _outside_model(scene) -> str | None:
    """Why a run with a constant torque lies outside the model (as a sweep's ``invalid``)."""
    from ..inputs import Constant
    from ..sweep import outside_validity

    torque = scene.inputs.torque
    return outside_validity(scene.effects, torque.value) if isinstance(torque, Constant) else None


def run(args) -> int:
    scene, t_from, extra = (_scene_from_file if args.scene else _scene_from_flags)(args)
    engine = args.engine or scene.solver.engine
    if args.fmu is not None and engine != "fmu":
        raise ValueError(f"--fmu {args.fmu}: the FMU runs with --engine fmu only (engine "
                         f"{engine})")
    _check_outputs(args)
    if engine == "fmu":  # the other engines warn in `gearpair.results.simulate`
        from ..results import _check_load

        _check_load(None, scene.params, scene.inputs.torque,
                    np.linspace(0.0, scene.t_end, 1001))
    outside = _outside_model(scene)
    if outside:  # run it (a user may want to see it), but never as if it were valid
        print(f"gearpair: warning: {outside}", file=sys.stderr)
    wall0 = time.perf_counter()
    try:
        traj = scene.run(engine, fmu_path=args.fmu)
    except (RuntimeError, ArithmeticError, ImportError) as exc:
        # a failed run or a missing extra, not bad input
        print(f"gearpair: error: {exc}", file=sys.stderr)
        return 1
    # run time apart from start-up (building the engine, loading its compiled code; the
    # FMU's instantiation and initialization)
    startup = traj.meta.get("startup_s")
    wall = traj.meta.get("wall_time_s", time.perf_counter() - wall0)
    summ = {"scene": scene.name, "engine": engine, "t_end": scene.t_end, **extra,
            "gear_changed": changed(scene.params), **traj.summary(t_from)}
    summ["events"] = int(np.sum(traj["n_events"]))
    summ["wall_time_s"] = wall
    summ["wall_time_per_simulated_s"] = wall / scene.t_end
    summ["startup_s"] = startup
    summ["outside_model"] = outside
    if args.out:
        from ..scenes import OUTPUT_NAMES

        names = scene.outputs.names if args.scene else None
        if names == OUTPUT_NAMES:  # the default: what this engine recorded (the FMU has less)
            names = [n for n in names if n in traj.data]
        traj.to_csv(args.out, names)
        summ["out"] = args.out
    if args.plot:
        try:
            traj.plot(args.plot, title=plot_title(scene, engine))
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
    elif "back_contact_ratio_sampled" in summ:
        print(f"  back-contact ratio   {summ['back_contact_ratio_sampled']:.4f} (of the "
              "output samples)")

    def stat(key: str, label: str) -> str:  # an FMU may give only samples
        return f"{label} {f[key] / 1e3:.2f}" if key in f else \
            f"{label} of the samples {f[key + '_sampled'] / 1e3:.2f}"

    print(f"  mesh force (kN)      {stat('min', 'min')}  {stat('mean', 'mean')}  "
          f"{stat('max', 'max')}")
    print(f"  DTE (um, samples)    mean {d['mean'] * 1e6:.3f}  peak-to-peak "
          f"{d['peak_to_peak'] * 1e6:.3f}")
    start = "" if startup is None else f"; start-up {startup:.2f} s apart"
    print(f"  wall time            {wall:.2f} s ({wall / scene.t_end:.3f} s per simulated s"
          f"{start})")
    for key in ("out", "plot"):
        if key in summ:
            print(f"  written {summ[key]}")
    return 0

