"""The first `gearpair simulate` on a machine says on stderr that it compiles the engine.

A child process with empty user caches runs the command line with the fast engine; the test
reads its stderr until the notice appears and then stops the child (the compile itself, 20-30 s,
is not waited for)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[1]


def test_first_cli_run_announces_the_compile(tmp_path):
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "xdg"),
               NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    env.pop("GEARPAIR_COMPILE_NOTICE", None)
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from gearpair.cli import main; "
         "sys.exit(main(sys.argv[1:]))", "simulate", "--engine", "fast", "--t-end", "0.001"],
        env=env, cwd=str(tmp_path), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        text=True)
    lines = []
    try:
        deadline = time.monotonic() + 300.0
        while time.monotonic() < deadline:
            line = proc.stderr.readline()
            if not line:
                break
            lines.append(line)
            if "compiling the fast engine" in line:
                break
    finally:
        proc.kill()
        proc.wait()
    notice = [ln for ln in lines if "compiling the fast engine" in ln]
    assert notice, lines
    assert notice[0].startswith("gearpair: compiling the fast engine once")
    assert str(tmp_path / "numba") in notice[0]  # where later runs load it from


# -- build_fmu.py says what it does before it compiles -------------------------------------
def _build_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("_build_fmu_progress", ROOT / "build_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_build_fmu_announces_the_engine_compile_before_it_starts(monkeypatch, tmp_path,
                                                                capsys):
    import gearpair
    import gearpair.aot

    seen = []

    def write_engine(folder, path=None, **target):  # the compile: what was said before it?
        seen.append(capsys.readouterr().err)
        raise RuntimeError("stop here")

    monkeypatch.setattr(gearpair.aot, "write_engine", write_engine)
    build = _build_module()
    with pytest.raises(RuntimeError, match="stop here"):
        build.compile_c_layer(b"<fmiModelDescription guid=\"x\"><ModelVariables/>"
                              b"</fmiModelDescription>", [], gearpair, tmp_path,
                              progress=build._stderr)
    assert seen[0].startswith("build_fmu: compiling the fast engine into the FMU's binary")
    assert "about 40 s the first time" in seen[0]
