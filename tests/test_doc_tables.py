"""The docs' effect tables are made from the declaration (`gearpair.effects.OPTIONS`, `RULES`)
by `gearpair.doc_tables`, and the pages hold the tables it makes now; an effect value or an
FMU code the docs' prose names is one the declaration allows."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from gearpair import doc_tables
from gearpair.effects import OPTIONS, Effects, check_option

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
# where each generated table stands
PAGES = {"scene_effects": "scenes.md", "model_effects": "model.md", "model_rules": "model.md",
         "fmu_effects": "fmu.md"}


def test_every_table_stands_on_its_page_and_is_current():
    assert set(PAGES) == set(doc_tables.TABLES)
    for name, page in PAGES.items():
        assert name in doc_tables.blocks((DOCS / page).read_text()), f"{page}: no {name}"
    assert doc_tables.stale(DOCS) == [], \
        "regenerate: .venv/bin/python -m gearpair.doc_tables docs"


def test_the_regeneration_command_finds_and_rewrites_a_stale_table(tmp_path):
    """The command the pages name: `--check` fails on a table that differs from the
    declaration, and the plain command puts the current one back (and nothing else)."""
    docs = tmp_path / "docs"
    shutil.copytree(DOCS, docs, ignore=shutil.ignore_patterns("*.png"))
    page = docs / "fmu.md"
    good = page.read_text()
    page.write_text(good.replace("| `friction_law` | Integer |", "| `friction_law` | Real |"))
    cmd = [sys.executable, "-m", "gearpair.doc_tables", str(docs)]
    check = subprocess.run([*cmd, "--check"], capture_output=True, text=True)
    assert check.returncode == 1 and "fmu.md: fmu_effects" in check.stderr
    fixed = subprocess.run(cmd, capture_output=True, text=True)
    assert fixed.returncode == 0, fixed.stderr
    assert page.read_text() == good
    assert subprocess.run([*cmd, "--check"]).returncode == 0


def test_an_unknown_table_name_is_refused():
    with pytest.raises(ValueError, match="unknown generated table 'nope'"):
        doc_tables.render("<!-- BEGIN nope -->\nx\n<!-- END nope -->\n")


def test_fmu_table_figures_are_the_slaves():
    """The start values and ranges the fmu.md table shows are the FMU's own variables'."""
    pytest.importorskip("pythonfmu")
    import importlib.util

    import gearpair

    spec = importlib.util.spec_from_file_location("_gp_slave_doc_tables",
                                                  ROOT / "fmu_src" / "GearPair.py")
    slave = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(slave)
    variables = {v["name"]: v for v in slave.interface(gearpair)}
    defaults = Effects().values()
    for name, m in OPTIONS.items():
        v = variables[m["fmu"]]
        assert v["start"] == doc_tables.fmu_start(m, defaults[name]), name
        assert (v["min"], v["max"]) == doc_tables.fmu_range(m), name


# a quoted string, a boolean, or a number that is not the start of an expression (2 mu)
_VALUE = (r"""("[^"\n]*"|'[^'\n]*'|\btrue\b|\bfalse\b|\bTrue\b|\bFalse\b"""
          r"|-?\d[\d.]*(?:e[-+]?\d+)?(?![\w.]|[ \t]*[a-zA-Z*/]))")
# `name = value`, optionally followed by the choice a code stands for: `dof = 1` (torsional)
_ASSIGN = re.compile(r"\b(\w+) ?= ?" + _VALUE + r"(`?\s*\((\w+)\))?")


def _mentions():
    for path in [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]:
        for m in _ASSIGN.finditer(path.read_text()):
            yield path.name, m.group(1), m.group(2), m.group(4)


def test_effect_values_and_codes_the_docs_name_are_allowed():
    """Every `effect = value` the docs write (scene, Python) is a value `Effects` allows, and
    every `fmu_parameter = code (choice)` is the code of that choice."""
    by_fmu = {m["fmu"]: m for m in OPTIONS.values()}
    seen = 0
    for page, name, raw, word in _mentions():
        m = OPTIONS.get(name) or by_fmu.get(name)
        if m is None:
            continue
        seen += 1
        where = f"{page}: {name} = {raw}"
        if m["kind"] == "choice" and re.fullmatch(r"\d+", raw):  # an FMU code
            assert name == m["fmu"] and int(raw) < len(m["fmu_choices"]), where
            assert word is None or word == m["fmu_choices"][int(raw)], f"{where} ({word})"
            continue
        if raw[0] in "\"'":
            value = raw[1:-1]
        elif raw in ("true", "false", "True", "False"):
            value = raw in ("true", "True")
        else:
            value = float(raw)
            if value == 0.0 and m["none"]:  # the FMU's and the scenes' 0 for None
                continue
        if m["kind"] == "choice":
            assert value in m["choices"], where
        else:
            check_option(name, value, m)
    assert seen >= 20, seen


def test_fmu_descriptions_write_every_code_with_its_choice():
    """An FMU parameter's description that names a coded value (its own or another's) writes
    it as `fmu_parameter = code (choice)`, generated from the declaration
    (`effects.say_fmu`), so the test above checks it in docs/fmu.md's table: no bare code,
    no `{field=value}` reference left unsaid."""
    coded = {m["fmu"]: m for m in OPTIONS.values() if m["kind"] == "choice"}
    names = "|".join(coded)
    for name, m in OPTIONS.items():
        doc = m["fmu_doc"]
        assert not re.search(r"\{\w+=", doc), (name, doc)
        for hit in re.finditer(rf"\b({names})\b(\W{{0,3}})(\d+)(?: \((\w+)\))?", doc):
            fmu, sep, code, word = hit.groups()
            assert sep == " = " and word == coded[fmu]["fmu_choices"][int(code)], \
                (name, hit[0])


def test_a_description_naming_a_value_the_declaration_lacks_fails():
    from gearpair.effects import _fmu_words

    assert _fmu_words("with {friction=stick_slip}, {separation=true}") == \
        "with friction_law = 3 (stick_slip), separation = true"
    with pytest.raises(ValueError, match="friction"):
        _fmu_words("{friction=stick}")
    with pytest.raises(KeyError):
        _fmu_words("{frictions=off}")
