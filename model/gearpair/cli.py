"""`gearpair` command line: thin wrappers over the core.

gearpair modes [SCENE.toml] [--set NAME=VALUE ...] [--bore-ratio R] [--first-mode-hz F] [--json]
gearpair simulate SCENE.toml [--engine fast|fmu|reference] [--out run.csv] [--plot run.png]
                  [--json] [--t-end S] [--set NAME=VALUE ...]
gearpair simulate [--json] [--out run.csv] [--t-end S] [--speed-rpm N] [--torque NM] ...
gearpair sweep PARAM VALUES [...]        gearpair bench [...]
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import os
import sys
import time
import warnings
from dataclasses import asdict, fields, replace

import numpy as np

from . import __version__
from .effects import (
    DOFS,
    FRICTION_LAWS,
    SLIDING_VARIANTS,
    STICK_TIES,
    STIFFNESS_KINDS,
    Effects,
    StiffnessSpec,
)
from .modal import SLIP_NAMES, derive_params, modes
from .params import RPM, RTOL_MAX, RTOL_MIN, GearParams, OperatingPoint

_GEAR_FIELDS = {f.name: f for f in fields(GearParams)}
_DERIVED = {"bore_ratio": ("m1", "J1", "m2", "J2"), "first_mode_hz": ("kr2",)}


def parse_set(items: list[str]) -> dict[str, float]:
    """``--set NAME=VALUE`` items as GearParams changes; ``ValueError`` (one line) for a
    malformed item, an unknown name (with the closest field) or a value that is no number.
    Ranges are checked by `GearParams` itself."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"--set {item!r}: use NAME=VALUE, e.g. --set module=0.004")
        if name == "pressure_angle_deg":
            name, scale = "pressure_angle", math.pi / 180.0
        else:
            scale = 1.0
        if name not in _GEAR_FIELDS:
            near = difflib.get_close_matches(name, list(_GEAR_FIELDS), n=1)
            hint = f" (did you mean {near[0]}?)" if near else ""
            raise ValueError(f"--set {name}: no such gear parameter{hint}; choose from "
                             f"{', '.join(_GEAR_FIELDS)}, pressure_angle_deg")
        try:
            value = float(text)
        except ValueError:
            raise ValueError(f"--set {item!r}: {text.strip()!r} is not a number") from None
        if isinstance(_GEAR_FIELDS[name].default, int):
            if value != int(value):
                raise ValueError(f"--set {item!r}: {name} must be a whole number")
            value = int(value)
        if name in out:
            raise ValueError(f"--set {name} is given twice")
        out[name] = value * scale if scale != 1.0 else value
    return out


def gear_from_args(args, base: GearParams, effects: Effects) -> GearParams:
    """``base`` with ``--set`` applied, then ``--bore-ratio`` and ``--first-mode-hz``
    derived (`gearpair.modal.derive_params`)."""
    changes = parse_set(args.set)
    for opt, derived in _DERIVED.items():
        clash = [k for k in derived if k in changes]
        if getattr(args, opt) is not None and clash:
            raise ValueError(f"--{opt.replace('_', '-')} derives {', '.join(derived)}: do not "
                             f"also --set {', '.join(clash)}")
    p = base.replace(**changes) if changes else base
    return derive_params(p, bore_ratio=args.bore_ratio, first_mode_hz=args.first_mode_hz,
                         effects=effects)


def _changed(p: GearParams) -> dict[str, float]:
    """The fields of ``p`` that differ from Table 1 (for the summaries)."""
    d = GearParams()
    return {k: v for k, v in asdict(p).items() if v != getattr(d, k)}


def model_description(effects: Effects) -> tuple[str, tuple[str, ...]]:
    """The linear models a run with ``effects`` moves through, in words, and their names:
    ``slip`` always (Eqs. 4-7, with the mean mesh stiffness; friction does not enter the
    stiffness), ``stick`` (Eq. 22) only with ``friction = "stick_slip"``, the only law
    under which teeth stick."""
    dof = ("torsional (u1, u2; rigid supports)" if effects.dof == "torsional"
           else "6-DOF (x, y, u of both gears)")
    if effects.friction == "stick_slip":
        return (f"{dof}, friction stick_slip, sliding {effects.sliding}: the slip and "
                "stick models", ("slip", "stick"))
    why = "friction off" if effects.friction == "off" else \
        f"friction {effects.friction}, which never sticks"
    return f"{dof}, {why}: the slip model only (teeth never stick)", ("slip",)


def _modes(args) -> int:
    if args.scene:
        from .scenes import load_scene

        if args.dof is not None or args.sliding is not None or args.friction is not None:
            raise ValueError("--dof, --sliding, --friction: set these in the scene file's "
                             "[effects]")
        scene = load_scene(args.scene)
        base, effects = scene.params, scene.effects
        source = f"scene {scene.name}"
    else:
        dof = args.dof or "full"
        sliding = args.sliding or "paper"
        # the torsional model sticks only with full sliding (`Effects`)
        friction = args.friction or ("nominal" if dof == "torsional" and sliding == "paper"
                                     else "stick_slip")
        effects = Effects(stiffness="constant", dof=dof, sliding=sliding, friction=friction)
        base = GearParams()
        source = "command line"
    if args.mu is not None:
        if any(i.partition("=")[0].strip() == "mu" for i in args.set):
            raise ValueError("give --mu or --set mu=..., not both")
        args.set = [*args.set, f"mu={args.mu}"]
    p = gear_from_args(args, base, effects)
    words, which_models = model_description(effects)
    free = [i for i, n in enumerate(SLIP_NAMES) if effects.dof == "full" or n in ("u1", "u2")]
    names = [SLIP_NAMES[i] for i in free]
    out: dict = {"model": {"source": source, "dof": effects.dof,
                           "friction": effects.friction, "sliding": effects.sliding,
                           "models": list(which_models), "description": words}}
    for which in ("slip", "stick"):
        if which not in which_models:
            out[which] = None  # the run never enters this model
            continue
        f, shapes = modes(p, which, effects=replace(effects, stiffness=StiffnessSpec("constant")))
        out[which] = {
            "frequencies_hz": [round(float(x), 6) for x in f],
            "coordinates": names,
            "mode_shapes": [[round(float(shapes[k, i]), 6) for k in free]
                            for i in range(len(f))],
        }
    out["params"] = asdict(p)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    changed = _changed(p)
    print("gear data: Table 1" + (" except " + ", ".join(f"{k} = {v:.6g}" for k, v in
                                                         changed.items()) if changed else ""))
    print(f"model ({source}): {words}")
    for which in which_models:
        d = out[which]
        print(f"{which} model: natural frequencies (Hz) and mode shapes (largest component 1)")
        print("  mode  f (Hz)     " + "  ".join(f"{n:>7s}" for n in names))
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
    """The flag-based run as a scene: constant inputs, Table 1 data with ``--mu`` and
    ``--set``."""
    from .inputs import Constant
    from .scenes import Inputs, OutputSpec, Scene, Solver

    if args.mu is not None and "mu" in parse_set(args.set):
        raise ValueError("give --mu or --set mu=..., not both")
    for k, v in _RUN_FLAGS.items():
        if getattr(args, k) is None:
            setattr(args, k, v)
    t_end = 0.2 if args.t_end is None else args.t_end
    if not (t_end > 0 and args.dt > 0):
        raise ValueError(f"--t-end = {t_end!r} and --dt = {args.dt!r} must be > 0 s")
    op = OperatingPoint(torque=args.torque, speed=args.speed_rpm * RPM)
    effects = _effects(args)
    scene = Scene(
        name="command line", params=gear_from_args(args, GearParams(mu=args.mu), effects),
        effects=effects,
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
    if args.set or args.bore_ratio is not None or args.first_mode_hz is not None:
        scene = replace(scene, params=gear_from_args(args, scene.params, scene.effects))
    if args.t_end is not None:
        scene = scene.with_t_end(args.t_end)
    return scene, scene.t_from, {"scene_file": str(args.scene)}


def _check_outputs(args) -> None:
    """Refuse what would fail only after the run: --out and --plot must be writable files
    (their folders are created, as ``sweep --out`` does) and the figure format known."""
    from .writable import check_writable

    for flag, path in (("--out", args.out), ("--plot", args.plot)):
        if path is not None:
            check_writable(flag, path)
    if args.plot:
        check_figure_format("--plot", args.plot)


def check_figure_format(flag: str, path: str) -> None:
    """``ValueError`` naming ``flag`` if matplotlib cannot write the suffix of ``path``
    (nothing is checked without matplotlib: the plot reports that after the run)."""
    from pathlib import Path

    try:
        from matplotlib.backend_bases import FigureCanvasBase
    except ImportError:
        return
    kinds = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix.lstrip(".").lower()
    if suffix not in kinds:
        raise ValueError(f"{flag} {path}: unknown figure format {suffix!r}; allowed "
                         + ", ".join(sorted(kinds)))


def _schedule_text(f, unit: str, scale: float = 1.0) -> str:
    """An input schedule in a few words (constant value, ramp, step, CSV series)."""
    from .inputs import Ramp, Series, Step

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
    gear = "" if not _changed(scene.params).keys() - {"mu"} else ", own gear data"
    return (f"{scene.name}: {_schedule_text(scene.inputs.speed, 'r/min', 1 / RPM)}, "
            f"{_schedule_text(scene.inputs.torque, 'N.m')}, mu {scene.params.mu:g}{gear}\n"
            f"{', '.join(eff)}; {engine} engine")


def _outside_model(scene) -> str | None:
    """Why a run with a constant torque lies outside the model (as a sweep's ``invalid``)."""
    from .inputs import Constant
    from .sweep import outside_validity

    torque = scene.inputs.torque
    return outside_validity(scene.effects, torque.value) if isinstance(torque, Constant) else None


def _simulate(args) -> int:
    scene, t_from, extra = (_scene_from_file if args.scene else _scene_from_flags)(args)
    engine = args.engine or scene.solver.engine
    _check_outputs(args)
    if engine == "fmu":  # the other engines warn in `gearpair.results.simulate`
        from .results import _check_load

        _check_load(None, scene.params, scene.inputs.torque,
                    np.linspace(0.0, scene.t_end, 1001))
    outside = _outside_model(scene)
    if outside:  # run it (a user may want to see it), but never as if it were valid
        print(f"gearpair: warning: {outside}", file=sys.stderr)
    wall0 = time.perf_counter()
    try:
        traj = scene.run(engine)
    except (RuntimeError, ArithmeticError, ImportError) as exc:
        # a failed run or a missing extra, not bad input
        print(f"gearpair: error: {exc}", file=sys.stderr)
        return 1
    # run time apart from start-up (building the engine, loading its compiled code; the
    # FMU's instantiation and initialization)
    startup = traj.meta.get("startup_s")
    wall = traj.meta.get("wall_time_s", time.perf_counter() - wall0)
    summ = {"scene": scene.name, "engine": engine, "t_end": scene.t_end, **extra,
            "gear_changed": _changed(scene.params), **traj.summary(t_from)}
    summ["events"] = int(np.sum(traj["n_events"]))
    summ["wall_time_s"] = wall
    summ["wall_time_per_simulated_s"] = wall / scene.t_end
    summ["startup_s"] = startup
    summ["outside_model"] = outside
    if args.out:
        from .scenes import OUTPUT_NAMES

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


def _add_gear_options(p: argparse.ArgumentParser) -> None:
    """``--set``, ``--bore-ratio``, ``--first-mode-hz``: own gear data (modes, simulate)."""
    g = p.add_argument_group("own gear data (Table 1 unless changed; applied over a scene's "
                             "[gear])")
    g.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="change a GearParams field in SI units (m, kg, kg.m2, N/m, rad; "
                   "pressure_angle_deg in degrees), e.g. --set module=0.004 --set z1=25; "
                   "repeatable; names and ranges in docs/scenes.md [gear]")
    g.add_argument("--bore-ratio", type=float, metavar="R",
                   help="derive m1, J1, m2, J2 from module, teeth and face width as steel "
                   "rings (7850 kg/m3) with bore diameter = R x pitch diameter, R in [0, 0.99] "
                   "(Table 1's bodies are R = 0.8; docs/model.md); default: keep them")
    g.add_argument("--first-mode-hz", type=float, metavar="HZ",
                   help="derive kr2 so that the slip model's first natural frequency is HZ "
                   "(the paper tunes it to 32 Hz for Table 1's gears); default: keep kr2")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="gearpair", description="Spur gear pair dynamics with stick-slip (Xun, Dai & "
        "Wang 2023): natural frequencies, simulation, parameter sweeps and benchmarks.",
        epilog="'gearpair COMMAND -h' lists the options of a command. Units are SI unless "
        "the option says otherwise.")
    ap.add_argument("--version", action="version", version=f"%(prog)s {__version__}",
                    help="print the version and exit")
    sub = ap.add_subparsers(dest="cmd", metavar="COMMAND")
    m = sub.add_parser("modes", help="natural frequencies and mode shapes (Figs. 5-6)",
                       description="Natural frequencies and mode shapes of the slip (Eqs. "
                       "4-7) and stick (Eq. 22) models with the mean mesh stiffness, for "
                       "Table 1's gears, a scene's [gear] or your own data: the models the "
                       "run would move through (its dof and friction; the stick model only "
                       "with stick_slip friction).")
    m.add_argument("scene", nargs="?", help="scene file (TOML, docs/scenes.md) whose [gear] "
                   "and [effects] dof/sliding/friction to use; default: Table 1")
    m.add_argument("--json", action="store_true", help="print frequencies (Hz), mode shapes "
                   "and the gear data used as JSON")
    m.add_argument("--mu", type=float, help="coefficient of friction, [0, 1] (accepted for "
                   "symmetry with simulate; the modes do not depend on it); default 0.02")
    m.add_argument("--dof", choices=DOFS, help="full 6-DOF or torsional (u1, u2) model; "
                   "default full")
    m.add_argument("--sliding", choices=SLIDING_VARIANTS, help="sliding velocity that the "
                   "stick model ties: paper (Eq. 12) or full; default paper")
    m.add_argument("--friction", choices=FRICTION_LAWS, help="friction law of the run: "
                   "only stick_slip adds the stick model; default stick_slip (nominal with "
                   "--dof torsional and paper sliding, which cannot stick)")
    _add_gear_options(m)
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
    run.add_argument("--stiffness", choices=[k for k in STIFFNESS_KINDS if k != "table"],
                     help=f"mesh stiffness law; default {d['stiffness']} (a table needs a "
                     "scene file)")
    run.add_argument("--friction", choices=FRICTION_LAWS, help="friction law: off, nominal "
                     "(the slip model), regularized or stick_slip (the paper's); default "
                     f"{d['friction']}")
    run.add_argument("--sliding", choices=SLIDING_VARIANTS, help="sliding velocity: paper "
                     f"(Eq. 12) or full; default {d['sliding']}")
    run.add_argument("--stick-tie", choices=STICK_TIES, help="how stuck teeth move together: "
                     f"exact (v = 0) or paper (Eq. 19); default {d['stick_tie']}")
    run.add_argument("--no-separation", action="store_true", default=None,
                     help="teeth never separate (a linear mesh spring); default: they do")
    _add_gear_options(s)
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


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one line on stderr, like the errors (no source file and line)."""
    print(f"gearpair: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    if args.cmd is None:  # bare `gearpair`: the help, and argparse's status for a usage error
        ap.print_help()
        return 2
    # a first run on a machine compiles the fast engine: say so on stderr (gearpair.jitcache)
    os.environ.setdefault("GEARPAIR_COMPILE_NOTICE", "1")
    with warnings.catch_warnings():
        warnings.showwarning = _warning_line
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
