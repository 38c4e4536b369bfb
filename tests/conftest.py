"""Shared fixtures: the GearPair FMU is built once per test session from the working tree."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _build_module():
    spec = importlib.util.spec_from_file_location("build_fmu", ROOT / "build_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="session")
def fmu_path(tmp_path_factory) -> Path:
    """A fresh build of GearPair.fmu (build_fmu.py, current sources) in a temporary folder."""
    pytest.importorskip("pythonfmu")
    out = tmp_path_factory.mktemp("fmu")
    path = _build_module().build(out)
    assert path == out / "GearPair.fmu" and path.is_file()
    return path


@pytest.fixture(scope="session")
def md(fmu_path):
    """The FMU's model description, read by fmpy."""
    fmpy = pytest.importorskip("fmpy")
    return fmpy.read_model_description(str(fmu_path))


@pytest.fixture
def no_runs(monkeypatch):
    """Any run (scene, sweep, bench) fails the test: the checks must come first."""
    import gearpair.bench
    import gearpair.sweep.study
    from gearpair.scenes import Scene

    def ran(*a, **k):
        raise AssertionError("the run started before the output check")

    monkeypatch.setattr(Scene, "run", ran)
    monkeypatch.setattr(gearpair.sweep.study, "run_grid", ran)
    monkeypatch.setattr(gearpair.bench, "run", ran)
