"""The docs' tables of the effects, made from their declaration (`gearpair.effects.OPTIONS`
and `RULES`): the scene keys (docs/scenes.md), the options and the refused combinations
(docs/model.md) and the FMU's effect parameters (docs/fmu.md).

A page holds a generated table between two markers, ``<!-- BEGIN name ... -->`` and
``<!-- END name -->``, ``name`` one of `TABLES`; everything between them is this module's.
After a change of `gearpair.effects`, from the repository's root::

    .venv/bin/python -m gearpair.doc_tables docs           # rewrite the tables in docs/*.md
    .venv/bin/python -m gearpair.doc_tables docs --check   # exit 1 naming a stale table

``tests/test_doc_tables.py`` fails while a page is stale.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .effects import ON, OPTIONS, RULES, VARIANT, Effects, Rule, fmu_code

BLOCK = re.compile(r"(<!-- BEGIN (\w+)\b[^\n]*-->\n)(.*?)(<!-- END \2 -->)", re.S)


def _word(value: Any) -> str:
    """A value as TOML (and the docs) write it, in backticks."""
    if isinstance(value, bool):
        return f"`{'true' if value else 'false'}`"
    return f'`"{value}"`' if isinstance(value, str) else f"`{value:g}`"


def _cell(text: str) -> str:
    """Text for a table cell: a ``|`` would end the cell."""
    return text.replace("|", "\\|")


def _py(value: Any) -> str:
    """A value as Python writes it, in backticks."""
    if isinstance(value, str):
        return f'`"{value}"`'
    return f"`{value}`" if value is None or isinstance(value, bool) else f"`{value:g}`"


def _range(m: dict, lo: float | None = None) -> str:
    lo = m["min"] if lo is None else lo
    return f"{'(' if m['lo_open'] else '['}{lo:g}, {m['max']:g}]"


def _unit(m: dict) -> str:
    return "" if m["unit"] in ("1", None) else m["unit"]


def _rule_text(rule: Rule, say: Callable[[str, Any], str],
               say_on: Callable[[str], str]) -> str:
    """``rule`` in a front door's words: ``say(field, value)`` an assignment, ``say_on(field)``
    the effect switched on."""
    name, allowed = rule.needs
    given = " with ".join(say_on(n) if v is ON else say(n, v) for n, v in rule.given)
    return f"{given} needs " + " or ".join(say(name, a) for a in allowed)


def _say_scene(name: str, value: Any) -> str:
    return f"`{name} = {_word(value)[1:-1]}`"


def scene_effects() -> str:
    """The ``[effects]`` table of docs/scenes.md: key, TOML type, allowed values, default,
    meaning with the combinations it takes part in."""
    defaults = Effects().values()
    rows = ["| key | type | allowed | default | meaning |", "| --- | --- | --- | --- | --- |"]
    for name, m in OPTIONS.items():
        default = defaults[name]
        if m["kind"] == "choice":
            typ = "string"
            allowed_ = ", ".join(_word(c) for c in m["fmu_choices"])
            if m["fmu_choices"] != m["choices"]:
                typ = "string or table"
                allowed_ += "; " + ", ".join(_word(c) for c in m["choices"]
                                             if c not in m["fmu_choices"]) + \
                    " only as a table (below)"
        elif m["kind"] == "bool":
            typ, allowed_ = "boolean", "`true`, `false`"
        else:
            typ = "number" + ("" if m["unit"] == "1" else f", {m['unit']}")
            allowed_ = _range(m)
            if m["zero_off"]:
                allowed_ += ", or 0 for off"
        shown = f"absent: {m['none']}" if default is None else _word(default)
        meaning = _cell(m["doc"])
        for rule in RULES:
            if any(n == name for n, _ in rule.given):
                said = _rule_text(rule, _say_scene, lambda n: f"a `{n}`")
                meaning += f". {said[0].upper()}{said[1:]}"
        rows.append(f"| `{name}` | {typ} | {allowed_} | {shown} | {meaning} |")
    return "\n".join(rows) + "\n"


def model_effects() -> str:
    """The options of `Effects` for docs/model.md: values, default, the value that leaves the
    effect out of the model, meaning."""
    defaults = Effects().values()
    rows = ["| `Effects` field | values | default | without the effect | meaning |",
            "| --- | --- | --- | --- | --- |"]
    for name, m in OPTIONS.items():
        if m["kind"] == "choice":
            values = ", ".join(_py(c) for c in m["choices"])
        elif m["kind"] == "bool":
            values = "`True`, `False`"
        else:
            values = _range(m) + (f" {_unit(m)}" if _unit(m) else "")
            if m["none"]:
                values += f"; `None`{' or 0' if m['zero_off'] else ''}: {m['none']}"
        default = defaults[name]
        off = m["off"]
        without = "none: every value is a variant" if off is VARIANT else _py(off)
        rows.append(f"| `{name}` | {values} | {_py(default)} | {without} | {_cell(m['doc'])} |")
    return "\n".join(rows) + "\n"


def model_rules() -> str:
    """The combinations `Effects` refuses, with why, for docs/model.md."""
    out = ""
    for rule in RULES:
        said = _rule_text(rule, lambda n, v: f"`{n} = {_py(v)[1:-1]}`",
                          lambda n: f"a `{n}`")
        out += f"- {said[0].upper()}{said[1:]}: {rule.why}.\n"
    return out


def fmu_start(m: dict, default: Any) -> Any:
    """The FMU parameter's start value of an effect whose `Effects` default is ``default``:
    a choice's code, a boolean, a number with 0 for None."""
    if m["kind"] == "choice":
        return m["fmu_choices"].index(default)
    if m["kind"] == "bool":
        return bool(default)
    return 0.0 if default is None else float(default)


def fmu_range(m: dict) -> tuple[Any, Any]:
    """The FMU parameter's (min, max): the codes of a choice, a number's range with 0 for
    None, (None, None) for a boolean."""
    if m["kind"] == "choice":
        return 0, len(m["fmu_choices"]) - 1
    if m["kind"] == "bool":
        return None, None
    return (0.0 if m["none"] else m["min"]), m["max"]


def _say_fmu(name: str, value: Any) -> str:
    choice = f" ({value})" if OPTIONS[name]["kind"] == "choice" else ""
    return f"`{fmu_code(name, value)}`{choice}"


def _say_fmu_on(name: str) -> str:
    m = OPTIONS[name]
    if m["kind"] == "number" and m["none"]:
        return f"`{m['fmu']} > 0`"
    return f"`{m['fmu']}` other than {_say_fmu(name, m['off'])}"


def fmu_effects() -> str:
    """The FMU's effect parameters for docs/fmu.md: name, type, codes or range, start value,
    the `Effects` field it sets, meaning; then the combinations refused at
    ``fmi2ExitInitializationMode``."""
    defaults = Effects().values()
    rows = ["| parameter | type | codes or range | start | sets `Effects` | meaning |",
            "| --- | --- | --- | --- | --- | --- |"]
    for name, m in OPTIONS.items():
        start = fmu_start(m, defaults[name])
        lo, _ = fmu_range(m)
        if m["kind"] == "choice":
            typ, allowed_ = "Integer", ", ".join(f"{i} {c}" for i, c in
                                                 enumerate(m["fmu_choices"]))
            shown = f"{start} ({defaults[name]})"
        elif m["kind"] == "bool":
            typ, allowed_, shown = "Boolean", "true, false", _word(start)[1:-1]
        else:
            typ = "Real" + (f", {_unit(m)}" if _unit(m) else "")
            if m["display_unit"]:
                typ += f" (shown in {m['display_unit']})"
            allowed_ = _range(m)
            if m["none"]:
                allowed_ = f"0: {m['none']}; else {allowed_}" if m["lo_open"] else \
                    f"{_range(m, lo)}; 0: {m['none']}"
            shown = f"{start:g}"
        rows.append(f"| `{m['fmu']}` | {typ} | {allowed_} | {shown} | `{name}` | "
                    f"{_cell(m['fmu_doc'])} |")
    rules = "".join(f"- {_rule_text(r, _say_fmu, _say_fmu_on)}: {r.why}.\n" for r in RULES)
    return "\n".join(rows) + "\n\nRefused at `fmi2ExitInitializationMode`, in the FMU's " \
        "names and codes:\n\n" + rules


TABLES: dict[str, Callable[[], str]] = {
    "scene_effects": scene_effects,
    "model_effects": model_effects,
    "model_rules": model_rules,
    "fmu_effects": fmu_effects,
}


def _body(name: str) -> str:
    """What stands between a block's markers: its table between blank lines (so that every
    Markdown reader ends the table before the closing marker)."""
    return "\n" + TABLES[name]() + "\n"


def render(text: str) -> str:
    """``text`` (a page) with every generated block made anew."""
    def block(match: re.Match) -> str:
        name = match.group(2)
        if name not in TABLES:
            raise ValueError(f"unknown generated table {name!r}; known: {', '.join(TABLES)}")
        return match.group(1) + _body(name) + match.group(4)

    return BLOCK.sub(block, text)


def blocks(text: str) -> list[str]:
    """The names of the generated blocks of a page, in order."""
    return [m.group(2) for m in BLOCK.finditer(text)]


def stale(folder: str | Path) -> list[str]:
    """``page: table`` for every generated block of ``folder``'s pages that is out of date."""
    out = []
    for page in sorted(Path(folder).glob("*.md")):
        for m in BLOCK.finditer(page.read_text()):
            name = m.group(2)
            if name not in TABLES or m.group(3) != _body(name):
                out.append(f"{page.name}: {name}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m gearpair.doc_tables",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", default="docs", help="the docs folder (docs)")
    ap.add_argument("--check", action="store_true",
                    help="only say which tables are stale (exit status 1 if any)")
    args = ap.parse_args(argv)
    if not Path(args.folder).is_dir():
        print(f"{args.folder}: no such folder", file=sys.stderr)
        return 2
    old = stale(args.folder)
    if args.check:
        for line in old:
            print(f"stale: {line}", file=sys.stderr)
        return 1 if old else 0
    for page in sorted(Path(args.folder).glob("*.md")):
        text = page.read_text()
        new = render(text)
        if new != text:
            page.write_text(new)
    for line in old:
        print(f"rewrote {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
