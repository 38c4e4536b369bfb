"""The first `gearpair simulate` on a machine says on stderr that it compiles the engine.

A child process with empty user caches runs the command line with the fast engine; the test
reads its stderr until the notice appears and then stops the child (the compile itself, 20-30 s,
is not waited for)."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

pytest.importorskip("numba")


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
