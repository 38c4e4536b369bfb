"""The fast engine stays a package a newcomer can change: no function in `gearpair.fast`
takes more than 8 parameters or is longer than 80 lines.

Parameters count as written (``self`` included, ``*args`` and ``**options`` one each); a
function's length runs from its ``def`` line to its last line (docstring and comments
included, decorators not). Run directly to list the longest and widest functions:

    .venv/bin/python tests/test_fast_limits.py
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "model" / "gearpair" / "fast"
MAX_PARAMS = 8
MAX_LINES = 80


def functions(package: Path = PACKAGE) -> list[tuple[str, int, int]]:
    """(module:function, parameters, lines) of every function and method in the package."""
    out = []
    for path in sorted(package.glob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) \
                    + (a.vararg is not None) + (a.kwarg is not None)
                out.append((f"{path.stem}:{node.name}", n, node.end_lineno - node.lineno + 1))
    return out


def test_the_package_has_its_modules():
    names = {p.stem for p in PACKAGE.glob("*.py")}
    assert {"__init__", "layout", "contact", "switching", "tableaux", "rk",
            "events", "lti", "loop", "engine"} <= names


def test_functions_stay_narrow():
    wide = [(f, n) for f, n, _ in functions() if n > MAX_PARAMS]
    assert not wide, f"more than {MAX_PARAMS} parameters: {wide}"


def test_functions_stay_short():
    long = [(f, n) for f, _, n in functions() if n > MAX_LINES]
    assert not long, f"longer than {MAX_LINES} lines: {long}"


def test_the_check_sees_a_violation(tmp_path):
    """The checker itself: a wide and a long function are caught."""
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_LINES))
    (tmp_path / "bad.py").write_text(
        f"def wide(a, b, c, d, e, f, g, h, *i):\n    pass\n\n\ndef long():\n{body}\n")
    found = {f: (n, lines) for f, n, lines in functions(tmp_path)}
    assert found["bad:wide"][0] == MAX_PARAMS + 1
    assert found["bad:long"][1] == MAX_LINES + 1


if __name__ == "__main__":
    rows = sorted(functions(), key=lambda r: -max(r[1] / MAX_PARAMS, r[2] / MAX_LINES))
    for f, n, lines in rows[:15]:
        print(f"{f:40s} {n:3d} parameters {lines:4d} lines")
