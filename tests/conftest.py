"""Shared fixtures: the GearPair FMU is built once per test run from the working tree."""

from __future__ import annotations

import fcntl
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _build_module():
    spec = importlib.util.spec_from_file_location("build_fmu", ROOT / "build_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# Under pytest-xdist with --dist loadfile (scripts/test.sh) a worker takes whole files: in the
# order below (the other files after them, in collection order), each worker the next one
# when it runs out. The longest go first, so that the two workers end within a short file of
# each other. The first two start at once and compile what the other does not, once each:
# test_fmu_start.py builds the FMU (its engine compiled for x86-64-v2) and compiles the FMU's
# engine in a child with empty caches; test_golden.py compiles this process's engine for
# every effect, method and driver into the numba cache, from which the other worker loads it
# later (both compiling it at once at the start cost some 25 s). The files after them start
# once the FMU is built: no worker waits for the other's build. The rest is in the order of
# their CPU time in a fresh-cache run (test_same_bits.py's children load the engine that
# test_golden.py compiled).
LONG_FILES = ("test_fmu_start.py", "test_golden.py", "test_core.py", "test_engine_object.py",
              "test_static_friction.py", "test_sweep_grid.py", "test_detmath.py",
              "test_hosts.py", "test_bench.py", "test_same_bits.py", "test_effects.py",
              "test_sensitivity.py", "test_fast_engine.py", "test_fmu_loading.py",
              "test_fmu_harness.py", "test_detlinalg.py", "test_scenes.py",
              "test_hard_cases.py", "test_contact_events.py", "test_sweep.py",
              "test_sweep_cluster.py", "test_properties.py")


def pytest_configure(config):
    # xdist (3.x) hands out files by their number of tests unless told not to: keep the order
    # of LONG_FILES (above)
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(config, items):
    if hasattr(config, "workerinput"):  # an xdist worker; each sorts alike (stable sort)
        rank = {name: i for i, name in enumerate(LONG_FILES)}
        items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture(scope="session")
def fmu_path(tmp_path_factory, request) -> Path:
    """A fresh build of GearPair.fmu (build_fmu.py, current sources) in a temporary folder.

    Under pytest-xdist (``-n 2``, scripts/test.sh) the workers share one build: the first
    to need it builds it into the run's common temporary folder while holding a lock on
    ``fmu.lock`` there; the others wait for it and use the same file (tests only read it)."""
    pytest.importorskip("pythonfmu")
    if not hasattr(request.config, "workerinput"):  # not an xdist worker
        return _built(tmp_path_factory.mktemp("fmu"))
    run = tmp_path_factory.getbasetemp().parent  # this run's folder, above each worker's
    with open(run / "fmu.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        out = run / "fmu"
        done = out / "GearPair.fmu"
        # the build renames the FMU and then its record into place: both there, it is whole
        if done.is_file() and (out / "GearPair.fmu.build.json").is_file():
            return done
        return _built(out)


def _built(out: Path) -> Path:
    path = _build_module().build(out)
    assert path == out / "GearPair.fmu" and path.is_file()
    assert sorted(p.name for p in out.iterdir()) == ["GearPair.fmu", "GearPair.fmu.build.json",
                                                     "GearPair3.fmu"]
    return path


@pytest.fixture(scope="session")
def fmu3_path(fmu_path) -> Path:
    """GearPair3.fmu, the FMI 3.0 build the same build writes beside GearPair.fmu."""
    path = fmu_path.with_name("GearPair3.fmu")
    assert path.is_file()
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
