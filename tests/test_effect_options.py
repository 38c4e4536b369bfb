"""Effects declared once: the front doors (scene keys, command line, FMU parameters and their
checks) follow `gearpair.effects.OPTIONS` and `RULES`, and the modules that read
an effect are the ones docs/architecture.md lists."""

from __future__ import annotations

import ast
import importlib.util
import re
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

import gearpair
from gearpair.effects import OPTIONS, RULES, Effects, StiffnessSpec
from gearpair.fast.layout import EFFECT_RECORDS

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "model" / "gearpair"
# a value other than the default for every effect (a valid combination with the others')
OTHER = {"stiffness": "rectangular", "separation": False, "friction": "regularized",
         "v_eps": 3e-4, "sliding": "full", "stick_tie": "paper", "backlash": 5e-5,
         "dof": "torsional", "mu_static": 0.03, "stribeck_velocity": 0.01}


def _slave():
    spec = importlib.util.spec_from_file_location("_gearpair_slave_options",
                                                  ROOT / "fmu_src" / "GearPair.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_effect_has_its_fmu_parameter_scene_key_and_flag():
    pytest.importorskip("pythonfmu")
    from gearpair.scenes.reading import _EFFECT_KEYS

    spec = {v["name"]: v for v in _slave().interface(gearpair)}
    defaults = Effects().values()
    flags = {a.dest for a in _simulate_actions()}
    assert set(OTHER) == set(OPTIONS) == set(_EFFECT_KEYS) == set(EFFECT_RECORDS)
    for name, m in OPTIONS.items():
        v = spec[m["fmu"]]
        assert v["causality"] == "parameter", name
        if m["kind"] == "choice":
            assert v["codes"] == m["fmu_choices"] and v["max"] == len(m["fmu_choices"]) - 1
            assert v["start"] == m["fmu_choices"].index(defaults[name])
        elif m["kind"] == "number":
            assert (v["unit"], v["max"]) == (m["unit"], m["max"]), name
            assert v["min"] == (0.0 if m["none"] else m["min"]), name
        else:
            assert v["type"] == "Boolean" and v["start"] == defaults[name]
        assert name in flags or f"no_{name}" in flags, name


# the subcommands that run the model: each has an option per effect
MODEL_COMMANDS = ("simulate", "sweep", "modes")


def _subcommands():
    from gearpair.cli import build_parser

    return next(a for a in build_parser()._actions if a.dest == "cmd").choices


def _simulate_actions():
    return _subcommands()["simulate"]._actions


@pytest.mark.parametrize("cmd", MODEL_COMMANDS)
def test_every_command_that_runs_the_model_has_an_option_per_effect(cmd):
    """A new `Effects` field is a new option of each of these commands, made from its
    metadata (`add_effect_options`: the same name, choices, type and meaning everywhere)."""
    from gearpair.cli.common import effect_flags

    acts = {a.dest: a for a in _subcommands()[cmd]._actions}
    ref = {a.dest: a for a in _simulate_actions()}
    assert {d.removeprefix("no_") for d in effect_flags()} == set(OPTIONS)
    for dest in effect_flags():
        name = dest.removeprefix("no_")
        assert dest in acts, f"gearpair {cmd} has no option for the effect {name}"
        a, r = acts[dest], ref[dest]
        assert (a.option_strings, a.choices, a.type, a.default) == \
            (r.option_strings, r.choices, r.type, r.default), (cmd, dest)
        meaning = OPTIONS[name]["doc"].replace("`", "")
        assert meaning in a.help.replace("%%", "%"), (cmd, dest)


def test_a_sweep_holds_every_effect():
    """`SweepSettings` has a field per effect with its default, and its points get them."""
    from dataclasses import fields

    from gearpair.sweep.settings import SweepSettings

    held = {f.name: f.default for f in fields(SweepSettings)}
    assert {n: held.get(n, "missing") for n in OPTIONS} == Effects().values()
    assert SweepSettings().effects() == Effects()
    other = {n: v for n, v in OTHER.items() if n not in ("friction", "stribeck_velocity",
                                                         "separation")}
    assert SweepSettings(**other).inputs("mu", 0.02)[1] == Effects(**other)


@pytest.mark.parametrize("name", list(OPTIONS))
def test_a_value_goes_through_scene_flag_and_fmu_unchanged(name, tmp_path):
    """The other value of each effect, written as a scene key, as a command-line option and
    as the FMU's start values that the slave decodes, gives the same `Effects`."""
    pytest.importorskip("pythonfmu")
    from gearpair.cli import build_parser
    from gearpair.cli.common import effects_from_args
    from gearpair.scenes import Scene, fmu_start_values, load_scene

    value = OTHER[name]
    kw = {name: value}
    if name == "dof":
        kw["sliding"] = "full"  # torsional stick-slip needs full sliding (RULES)
    if name == "stribeck_velocity":
        kw["mu_static"] = 0.03
    if name == "backlash":
        kw["separation"] = True
    want = Effects(**kw)

    def toml(v):
        return ("true" if v else "false") if isinstance(v, bool) else \
            f'"{v}"' if isinstance(v, str) else repr(v)

    scene_file = tmp_path / "s.toml"
    scene_file.write_text("t_end = 0.01\n[effects]\n" + "".join(
        f"{k} = {toml(v)}\n" for k, v in kw.items()))
    assert load_scene(scene_file).effects == want

    argv = ["simulate"]
    for k, v in kw.items():
        if isinstance(v, bool):
            if not v:
                argv.append(f"--no-{k.replace('_', '-')}")
        else:
            argv += [f"--{k.replace('_', '-')}", str(v)]
    assert effects_from_args(build_parser().parse_args(argv)) == want
    # the same options of sweep (every point's effects) and modes (the mean stiffness)
    from gearpair.cli import modes, sweep

    args = build_parser().parse_args(["sweep", "mu", "0.02", *argv[1:]])
    assert sweep.settings_from_args(args).effects() == want
    args = build_parser().parse_args(["modes", *argv[1:]])
    assert modes.model_of(args)[1] == replace(want, stiffness=StiffnessSpec("constant"))

    slave = _slave()
    spec = slave.interface(gearpair)
    variables = {v["name"]: SimpleNamespace(description=v["description"]) for v in spec}
    start = fmu_start_values(Scene(name="x", effects=want), variables)
    values = {v["name"]: v["start"] for v in spec if v["causality"] == "parameter"}
    values.update(start)
    ns = SimpleNamespace(**values, _gp=gearpair)
    ns._decode = lambda n, codes: slave.GearPair._decode(ns, n, codes)
    assert slave.GearPair._effects(ns, gearpair.effects) == want


@pytest.mark.parametrize("rule", RULES, ids=lambda r: r.needs[0])
def test_rules_refuse_in_both_front_doors(rule):
    """Each refused combination is refused by `Effects` and by the FMU, each in its own
    words, from the one rule."""
    pytest.importorskip("pythonfmu")
    from gearpair.effects import ON

    values = Effects().values()
    for name, want in rule.given:
        values[name] = OTHER[name] if want is ON else want
    field, allowed = rule.needs
    m = OPTIONS[field]
    values[field] = next(v for v in (m["choices"] or (True, False)) if v not in allowed)
    assert rule.refuses(values)
    with pytest.raises(ValueError, match=re.escape(rule.why)):
        Effects(**values)
    msg = _slave()._combination_error(gearpair.effects, values)
    assert msg is not None and msg.endswith(rule.why)
    assert OPTIONS[field]["fmu"] + " = " in msg  # the FMU's names


def _readers() -> dict[str, set[str]]:
    """Effect -> the package modules (outside its front doors) that read it: its `Effects`
    field as an attribute in Python, its record names in the compiled code (`fast/`)."""
    out: dict[str, set[str]] = {name: set() for name in OPTIONS}
    front = ("cli/", "scenes/", "sweep/", "bench/")
    for f in sorted(PACKAGE.rglob("*.py")):
        rel = f.relative_to(PACKAGE).as_posix()
        if rel.startswith(front):
            continue
        tree = ast.parse(f.read_text())
        attrs = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
        ids = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
        for name in OPTIONS:
            if rel.startswith("fast/"):
                hit = bool(set(EFFECT_RECORDS[name]) & ids)
            else:
                hit = name in attrs or rel == "effects.py"
            if hit:
                out[name].add(rel)
    return out


def test_architecture_lists_the_modules_an_effect_touches():
    doc = (ROOT / "docs" / "architecture.md").read_text()
    section = doc.split("## What an effect touches", 1)[1].split("\n## ", 1)[0]
    physics = section.split("no others", 1)[1]
    listed = {p for p in re.findall(r"`([\w/]+\.py)`", physics) if not p.startswith("tests/")}
    readers = _readers()
    touched = set().union(*readers.values())
    assert touched <= listed, {n: sorted(r - listed) for n, r in readers.items() if r - listed}
    # and no module listed that no effect reads (the Runge-Kutta core is named as untouched)
    assert listed - touched <= {"params.py", "rk.py", "tableaux.py"}, listed - touched
    for name, files in readers.items():  # every effect reaches both engines' code
        assert "equations.py" in files and "fast/setup.py" in files, name
