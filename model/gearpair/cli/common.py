"""Option helpers shared by the subcommands: own gear data (``--set``, ``--bore-ratio``,
``--first-mode-hz``), figure files, the one-line warnings."""

from __future__ import annotations

import argparse
import difflib
import math
import sys
from dataclasses import asdict, fields

from ..effects import OPTIONS, Effects, StiffnessSpec, allowed
from ..modal import derive_params
from ..params import GearParams

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


def changed(p: GearParams) -> dict[str, float]:
    """The fields of ``p`` that differ from Table 1 (for the summaries)."""
    d = GearParams()
    return {k: v for k, v in asdict(p).items() if v != getattr(d, k)}



def add_gear_options(p: argparse.ArgumentParser) -> None:
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



def effect_flags() -> dict[str, object]:
    """dest -> default of the effect options `add_effect_options` adds (Effects' defaults;
    ``no_<name>`` for an effect that is on by default)."""
    defaults = Effects().values()
    return {(f"no_{n}" if m["kind"] == "bool" and defaults[n] else n):
            (False if m["kind"] == "bool" and defaults[n] else defaults[n])
            for n, m in OPTIONS.items()}


def add_effect_options(g, notes: dict[str, str] | None = None) -> None:
    """One option per `Effects` field, made from its metadata (`gearpair.effects.OPTIONS`):
    its choices (those one word selects: a stiffness table needs a scene file), a number in
    its unit and range, or ``--no-NAME`` for an effect that is on by default; with its
    meaning and default. Every subcommand that runs the model adds them here, so a new field
    is a new option of each. ``notes``: field -> a subcommand's own words, put before the
    default (e.g. what the field means for ``modes``). Unset (None) unless given:
    `effects_from_args` fills the defaults."""
    defaults, notes = Effects().values(), notes or {}
    for name, m in OPTIONS.items():
        flag, default = "--" + name.replace("_", "-"), defaults[name]
        doc = _plain(m["doc"]) + (f" ({_plain(notes[name])})" if name in notes else "")
        if m["kind"] == "choice":
            g.add_argument(flag, choices=m["fmu_choices"], help=f"{doc}; default {default}")
        elif default is True:
            g.add_argument(f"--no-{name.replace('_', '-')}", action="store_true", default=None,
                           help=f"without it: {doc}; default: with it")
        elif m["kind"] == "bool":
            g.add_argument(flag, action="store_true", default=None,
                           help=f"{doc}; default: without it")
        else:
            shown = f"none ({m['none']})" if default is None else f"{default:g}"
            g.add_argument(flag, type=float,
                           help=f"{doc}; allowed {allowed(m)}; default {shown}")


def effect_options_given(args) -> list[str]:
    """The effect options (`add_effect_options`) given on the command line, as typed."""
    return ["--" + k.replace("_", "-") for k in effect_flags()
            if getattr(args, k) not in (None, False)]


def effects_from_args(args) -> Effects:
    """The `Effects` of the effect options (`add_effect_options`); an option not given
    (None) takes the field's default."""
    kw, defaults = {}, Effects().values()
    for name, m in OPTIONS.items():
        if m["kind"] == "bool" and defaults[name]:
            kw[name] = not getattr(args, f"no_{name}")
        else:
            given = getattr(args, name)
            kw[name] = defaults[name] if given is None else given
    kw["stiffness"] = StiffnessSpec(kind=kw["stiffness"])
    return Effects(**kw)


def _plain(doc: str) -> str:
    """A docs text as --help prints it (no Markdown backticks; argparse formats %)."""
    return doc.replace("`", "").replace("%", "%%")


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



def warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one line on stderr, like the errors (no source file and line)."""
    print(f"gearpair: warning: {message}", file=sys.stderr)

