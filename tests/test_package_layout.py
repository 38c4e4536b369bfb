"""The package's shape: no import circle between its modules, every command-line module imports
on its own, the command line's parser loads no subcommand's machinery, and docs/architecture.md
is the module map of every module."""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "model" / "gearpair"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path) -> set[str]:
    """The package's modules that ``name`` imports anywhere in its text (also inside
    functions: a lazy import closes a circle as surely once both sides have run), except
    under ``if TYPE_CHECKING:`` (annotations only)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):  # `if TYPE_CHECKING:` imports never run
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING":
            node.body = []
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            for a in node.names:  # `from . import x`: x may be a module or a name in base
                out.add(f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base)
    return {m for m in out if m in MODULES and m != name}


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_the_import_graph_has_no_circle():
    graph = {name: _imports(name, path) for name, path in MODULES.items()}
    assert "gearpair.cli.bench" in graph["gearpair.cli"]  # the graph sees relative imports
    assert _circles(graph) == []


def test_a_circle_is_found():
    """The check above can fail: the former bench -> bench.cli -> cli -> bench."""
    graph = {"gearpair.bench": {"gearpair.bench.cli"}, "gearpair.bench.cli": {"gearpair.cli"},
             "gearpair.cli": {"gearpair.bench", "gearpair.params"}, "gearpair.params": set()}
    assert _circles(graph) == [["gearpair.bench", "gearpair.bench.cli", "gearpair.cli"]]


CLI_MODULES = sorted(m for m in MODULES if m.startswith("gearpair.cli") and
                     not m.endswith("__main__"))


@pytest.mark.parametrize("module", CLI_MODULES)
def test_each_command_line_module_imports_alone(module):
    """In a fresh interpreter, so no earlier import hides an order dependence."""
    subprocess.run([sys.executable, "-c", f"import {module}"], check=True, timeout=120)


def test_building_the_parser_loads_no_benchmark_or_engine():
    code = ("import sys; from gearpair.cli import build_parser; build_parser(); "
            "print(sorted(m for m in sys.modules if m.startswith(('gearpair.bench', "
            "'gearpair.fast', 'gearpair.reference', 'numba', 'dask'))))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True, timeout=120).stdout
    assert out.strip() == "[]"


def _module_map() -> set[str]:
    """The modules docs/architecture.md's layout block names, as paths in the package
    (``fast/loop.py``); a folder line (``cli/``) opens a sub-package for the lines under it."""
    doc = (PACKAGE.parents[1] / "docs" / "architecture.md").read_text()
    block = re.search(r"```\ngearpair/\n(.*?)```", doc, re.S).group(1)
    named, folder = set(), ""
    for line in block.splitlines():
        indent = len(line) - len(line.lstrip(" "))
        if indent not in (2, 4) or not line.strip():  # description lines, fmu_src/
            continue
        head = re.split(r"\s{2,}", line.strip())[0]
        for name in (p.strip() for p in head.split(",") if p.strip()):
            if name.endswith("/"):
                folder = name
                named.add(name + "__init__.py")
            else:
                named.add((folder if indent == 4 else "") + name)
    return named


def test_the_module_map_names_every_module_and_no_other():
    """docs/architecture.md is the one module map: every module of the package is in it
    (a sub-package's ``__init__`` by its folder line), and it names no module that is gone."""
    actual = {p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.py")
              if "__pycache__" not in p.parts}
    named = _module_map()
    assert sorted(actual - named - {"__init__.py"}) == []
    assert sorted(named - actual) == []


# -- a package that stands alone --------------------------------------------------------------
def test_no_module_reaches_above_the_package():
    """``Path(__file__).parents[k]`` stays inside the package (k at most the module's depth
    in it): the package never looks for a repository, whose files an installed wheel lacks."""
    above = []
    for rel, path in ((p.relative_to(PACKAGE), p) for p in MODULES.values()):
        depth = len(rel.parts) - 1  # gearpair/bench/x.py: parents[1] is gearpair/
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Subscript) and getattr(node.value, "attr", "") == "parents":
                k = node.slice.value if isinstance(node.slice, ast.Constant) else None
                if not isinstance(k, int) or k > depth:
                    above.append(f"{rel.as_posix()}:{node.lineno} parents[{k}]")
    assert above == []


_INSTALLED = r"""
import pathlib, sys
import gearpair
from gearpair.bench import nativestep, plain_scipy, settings

lib = pathlib.Path(sys.argv[1]).resolve()
assert pathlib.Path(gearpair.__file__).resolve().is_relative_to(lib), gearpair.__file__
for f in (settings.NOOP_SCRIPT, settings.HOST_SOURCE, settings.FMI3_HOST_SOURCE,
          nativestep.LOOP_SOURCE,
          settings.HERE.parent / "stepblock.py",
          pathlib.Path(plain_scipy.__file__)):
    assert f.resolve().is_relative_to(lib) and f.is_file(), f
print("ok")
"""


def test_the_installed_package_holds_every_file_the_bench_reads(tmp_path):
    """What a wheel installs (setuptools' ``build_py`` under the project's pyproject.toml: the
    packages with their package data), imported with no repository around it, finds the
    bench's own files inside itself: the no-op slave, the C timing hosts, the native
    step's loop, the step block's layout and the plain scipy model."""
    root = PACKAGE.parents[1]
    src, lib = tmp_path / "src", tmp_path / "lib"
    (src / "model").mkdir(parents=True)
    for name in ("pyproject.toml", "README.md"):
        (src / name).write_bytes((root / name).read_bytes())
    shutil.copytree(PACKAGE, src / "model" / "gearpair",
                    ignore=shutil.ignore_patterns("__pycache__", "_compiled", "*.pyc"))
    subprocess.run([sys.executable, "-c", "from setuptools import setup; setup()", "-q",
                    "build_py", "-d", str(lib)], cwd=src, check=True, capture_output=True,
                   timeout=120)
    for host in ("fmi2_bench_host.c", "fmi3_bench_host.c", "native_step_loop.c"):
        assert (lib / "gearpair" / "bench" / host).is_file(), host
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", _INSTALLED, str(lib)], cwd=tmp_path,
                         env={**env, "PYTHONPATH": str(lib)}, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]
