"""What a newcomer still tripped on after issue 17's fixes: `modes` of the model a scene runs,
output options checked before a run, a load plausibility warning, progress of the slow steps
(`bench --quick`, `build_fmu.py`)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gearpair.cli import main

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "examples" / "scenes"


# -- modes of the model the scene simulates ------------------------------------------------------
def test_modes_of_a_torsional_friction_off_scene_are_the_slip_model_in_u1_u2(capsys):
    assert main(["modes", str(SCENES / "nvh_torsional.toml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"]["models"] == ["slip"] and out["model"]["friction"] == "off"
    assert out["stick"] is None  # friction off: the teeth never stick
    slip = out["slip"]
    assert slip["coordinates"] == ["u1", "u2"]
    assert len(slip["frequencies_hz"]) == 2 and all(len(s) == 2 for s in slip["mode_shapes"])
    assert main(["modes", str(SCENES / "nvh_torsional.toml")]) == 0
    text = capsys.readouterr().out
    assert "torsional (u1, u2; rigid supports), friction off: the slip model only" in text
    assert "stick model" not in text and "x1" not in text


def test_modes_of_a_stick_slip_scene_keep_both_models(capsys):
    assert main(["modes", str(SCENES / "paper_stick_slip.toml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"]["models"] == ["slip", "stick"]
    assert len(out["slip"]["frequencies_hz"]) == 6 and len(out["stick"]["frequencies_hz"]) == 5


def test_torsional_stick_model_has_one_mode_in_u1_u2(capsys):
    """Rigid supports leave u1 and u2; a stuck pair ties them: one mode, no x or y."""
    assert main(["modes", "--dof", "torsional", "--sliding", "full", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"]["friction"] == "stick_slip"
    assert out["stick"]["coordinates"] == ["u1", "u2"]
    assert len(out["stick"]["frequencies_hz"]) == 1
    assert main(["modes", str(SCENES / "nvh_torsional.toml"), "--friction", "off"]) == 2
    assert "--friction: set these in the scene file" in capsys.readouterr().err


# -- output options checked before the run ------------------------------------------------------
# /proc exists but takes no new files, even for root (a chmod'ed folder would not stop root)
UNWRITABLE = Path("/proc")
needs_proc = pytest.mark.skipif(not UNWRITABLE.is_dir(), reason="needs Linux /proc")


@pytest.fixture
def no_runs(monkeypatch):
    """Any run (scene, sweep, bench) fails the test: the checks must come first."""
    import gearpair.bench
    import gearpair.sweep
    from gearpair.scenes import Scene

    def ran(*a, **k):
        raise AssertionError("the run started before the output check")

    monkeypatch.setattr(Scene, "run", ran)
    monkeypatch.setattr(gearpair.sweep, "run_sweep", ran)
    monkeypatch.setattr(gearpair.bench, "run", ran)


def _one_line_error(capsys, *words):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


@needs_proc
@pytest.mark.parametrize("argv, flag", [
    (["simulate", "--out", str(UNWRITABLE / "run.csv")], "--out"),
    (["simulate", "--plot", str(UNWRITABLE / "run.png")], "--plot"),
    (["sweep", "mu", "0.01,0.02", "--scheduler", "serial", "--out", str(UNWRITABLE / "sw")],
     "--out"),
    (["bench", "--quick", "--plot", str(UNWRITABLE / "wp.png")], "--plot"),
])
def test_unwritable_output_folder_is_refused_before_the_run(argv, flag, no_runs, capsys):
    assert main(argv) == 2
    _one_line_error(capsys, f"gearpair: error: {flag} {UNWRITABLE}", "cannot write")


def test_sweep_prefix_whose_file_is_a_folder_is_refused_before_the_run(tmp_path, no_runs,
                                                                       capsys):
    (tmp_path / "speed.json").mkdir()  # PREFIX.json cannot be written
    assert main(["sweep", "mu", "0.01", "--scheduler", "serial", "--out",
                 str(tmp_path / "speed")]) == 2
    _one_line_error(capsys, f"--out {tmp_path / 'speed'}", "speed.json, which it would "
                    "write, is a folder")
    # --no-plot: PREFIX.png is not written, so a folder of that name is no obstacle
    (tmp_path / "other.png").mkdir()
    with pytest.raises(AssertionError, match="run started"):
        main(["sweep", "mu", "0.01", "--scheduler", "serial", "--no-plot", "--out",
              str(tmp_path / "other")])


def test_bench_plot_format_is_checked_before_the_run(tmp_path, no_runs, capsys):
    assert main(["bench", "--quick", "--plot", str(tmp_path / "wp.xyz")]) == 2
    _one_line_error(capsys, "--plot", "unknown figure format 'xyz'")


# -- build_fmu.py says what it does before its minutes of compiling ------------------------------
def _build_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("_build_fmu_progress", ROOT / "build_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_build_fmu_announces_the_engine_compile_before_it_starts(monkeypatch, tmp_path,
                                                                capsys):
    import gearpair.shipped

    seen = []

    def ship(package, import_name):  # stands in for the compile: what was said before it?
        seen.append(capsys.readouterr().err)
        return {"files": 42, "compiled": {"source": "compiled", "seconds": 100.0}}

    monkeypatch.setattr(gearpair.shipped, "ship", ship)
    _build_module()._add_compiled_engine(tmp_path, "gearpair")
    before = seen[0]
    assert before.startswith("build_fmu: compiling the fast engine that the FMU ships")
    assert "a few minutes the first time" in before
    after = capsys.readouterr().err
    assert after.startswith("build_fmu: fast engine compiled in ") and "42 files" in after
