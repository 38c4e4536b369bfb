"""``gearpair modes``: natural frequencies and mode shapes of the slip and stick models."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict, replace

from ..effects import Effects, StiffnessSpec
from ..modal import SLIP_NAMES, modes
from ..params import GearParams
from .common import (
    add_effect_options,
    add_gear_options,
    changed,
    effect_options_given,
    effects_from_args,
    gear_from_args,
)

# what an effect means for the modes, beside its meaning for a run
_NOTES = {"dof": "the modes of the 6-DOF or the torsional (u1, u2) model",
          "sliding": "the sliding velocity that the stick model ties",
          "friction": "only stick_slip adds the stick model; the default is nominal with "
                      "--dof torsional and paper sliding, which cannot stick",
          "stiffness": "the modes use the mean mesh stiffness whatever the law"}


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``modes`` on the ``gearpair`` subparsers object."""
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
    add_effect_options(m.add_argument_group(
        "effects (without a scene file; docs/scenes.md [effects]): dof, sliding and friction "
        "choose the models; the others are checked and leave the modes unchanged"),
        notes=_NOTES)
    add_gear_options(m)
    return m


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


def model_of(args) -> tuple[GearParams, Effects, str]:
    """The base gear data, the effects (with the mean mesh stiffness) and their source:
    the scene file's, or Table 1 and the effect options."""
    if args.scene:
        from ..scenes import load_scene

        given = effect_options_given(args)
        if given:
            raise ValueError(f"{', '.join(given)}: set these in the scene file's [effects]")
        scene = load_scene(args.scene)
        return scene.params, scene.effects, f"scene {scene.name}"
    if args.friction is None:  # the torsional model sticks only with full sliding
        torsional_paper = (args.dof or Effects().dof) == "torsional" and \
            (args.sliding or Effects().sliding) == "paper"
        args.friction = "nominal" if torsional_paper else Effects().friction
    # the mean mesh stiffness (`modal.modes`), whatever --stiffness says
    effects = replace(effects_from_args(args), stiffness=StiffnessSpec("constant"))
    return GearParams(), effects, "command line"


def run(args) -> int:
    base, effects, source = model_of(args)
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
    own = changed(p)
    print("gear data: Table 1" + (" except " + ", ".join(f"{k} = {v:.6g}" for k, v in
                                                         own.items()) if own else ""))
    print(f"model ({source}): {words}")
    for which in which_models:
        d = out[which]
        print(f"{which} model: natural frequencies (Hz) and mode shapes (largest component 1)")
        print("  mode  f (Hz)     " + "  ".join(f"{n:>7s}" for n in names))
        for i, f in enumerate(d["frequencies_hz"]):
            row = "  ".join(f"{v:7.3f}" for v in d["mode_shapes"][i])
            print(f"  {i + 1:4d}  {f:9.3f}  {row}")
    return 0

