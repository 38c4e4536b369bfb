"""The docs stand alone and their commands work: every command runs from the venv, the model's
reconstruction is in the repository, snippets compile, the CSV input example feeds every
input of the FMU, and the platforms the FMU ships for are named."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _code_blocks(text: str) -> list[str]:
    return re.findall(r"```(?:bash|sh|console)?\n(.*?)```", text, flags=re.S)


def test_docs_run_commands_from_the_venv():
    """After the README's setup only .venv/bin has gearpair, fmpy, dask, pytest on it."""
    for path in DOCS:
        for block in _code_blocks(path.read_text()):
            for line in block.splitlines():
                cmd = line.strip()
                first = cmd.split(" ", 1)[0] if cmd else ""
                assert first not in ("gearpair", "fmpy", "python", "pytest", "dask", "ruff"), \
                    f"{path.name}: {cmd}"


def test_model_reconstruction_is_in_the_repository():
    readme = (ROOT / "README.md").read_text()
    assert "../shared" not in readme and "docs/model.md" in readme
    for path in DOCS:
        assert "MODEL.md" not in path.read_text(), path.name  # the private notes' name
    model = (ROOT / "docs" / "model.md").read_text()
    for eq in ("(1)", "(3)", "(8)", "(9)", "(12)", "(14)", "(26)", "(27)"):
        assert f"Eq. {eq}" in model or f"Eqs. {eq}" in model or eq in model, eq
    for topic in ("coordinates", "mesh stiffness", "backlash", "friction", "stick",
                  "sliding velocity", "stick ratio", "contact-loss ratio", "Own gear data"):
        assert topic.lower() in model.lower(), topic


def test_sweep_doc_snippet_guards_its_entry_point():
    doc = (ROOT / "docs" / "sweep.md").read_text()
    snippet = re.search(r"```python\n(.*?)```", doc, flags=re.S).group(1)
    assert 'if __name__ == "__main__":' in snippet
    compile(snippet, "sweep.md", "exec")


def test_csv_input_example_gives_every_fmu_input():
    doc = (ROOT / "docs" / "fmu.md").read_text()
    header = re.search(r"printf '([a-z_,]+)\\n", doc).group(1).split(",")
    pytest.importorskip("pythonfmu")
    import importlib.util

    spec = importlib.util.spec_from_file_location("_gp_slave2", ROOT / "fmu_src" / "GearPair.py")
    slave = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(slave)
    inputs = [v["name"] for v in slave.interface() if v["causality"] == "input"]
    assert header[0] == "time" and set(inputs) <= set(header[1:])


def test_readme_names_the_platform_tested_and_every_platform_shipped(fmu_path):
    """The README names the platform this suite runs on, and every platform the built FMU
    holds a binary for."""
    import platform
    import zipfile

    readme = (ROOT / "README.md").read_text()
    assert f"{platform.system()} {platform.machine()}" in readme
    with zipfile.ZipFile(fmu_path) as z:
        platforms = {n.split("/")[1] for n in z.namelist()
                     if n.startswith("binaries/") and n.count("/") >= 2}
    assert platforms
    for plat in platforms:
        assert plat in readme, plat


def _doc_commands() -> list[tuple[str, str]]:
    """(doc name, command) for every command line of the docs' shell blocks: continuation
    lines joined, comments dropped, `a; b` split."""
    out = []
    for path in DOCS:
        for block in _code_blocks(path.read_text()):
            for line in block.replace("\\\n", " ").splitlines():
                line = re.sub(r"\s#.*$", "", line).strip()
                if line and not line.startswith("#"):
                    out += [(path.name, c.strip()) for c in line.split("; ") if c.strip()]
    return out


def test_paths_the_docs_commands_name_exist():
    """Every repository file a docs command names (a scene, a script, an example) exists."""
    named = 0
    for doc, cmd in _doc_commands():
        for word in cmd.split():
            if re.match(r"(examples|benchmarks|scripts|tests|docs|fmu_src)/\S+\.\w+$", word) \
                    or word == "build_fmu.py":
                named += 1
                assert (ROOT / word).exists(), f"{doc}: {cmd}: no {word}"
    assert named >= 10


# `gearpair` subcommands that return in seconds: no engine run, no compile
_CHEAP = re.compile(r"^\.venv/bin/gearpair (modes\b|--version$|\S+ -h$)")


def test_the_docs_cheap_commands_run():
    """The docs' `gearpair modes`, `--version` and `-h` commands run and exit 0 (the others
    simulate, sweep or build; their front doors are tested in their own files)."""
    import shlex
    import subprocess
    import sys

    gearpair = Path(sys.executable).parent / "gearpair"
    if not gearpair.exists():
        pytest.skip("the gearpair command is not installed beside this interpreter")
    cheap = [(doc, cmd) for doc, cmd in _doc_commands() if _CHEAP.match(cmd)]
    assert len(cheap) >= 4, cheap
    for doc, cmd in cheap:
        argv = [str(gearpair), *shlex.split(cmd)[1:]]
        proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"{doc}: {cmd}\n{proc.stderr[-2000:]}"
        assert proc.stdout.strip(), f"{doc}: {cmd} printed nothing"
