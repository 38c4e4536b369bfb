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
    assert "about 30 s the first time" in before
    after = capsys.readouterr().err
    assert after.startswith("build_fmu: fast engine compiled in ") and "42 files" in after


# -- a torque the teeth cannot carry ----------------------------------------------------------
USER_GEAR = dict(module=4e-3, z1=25, z2=60, face_width=0.04, km_mean=8e8)
USER_SET = [a for k, v in USER_GEAR.items() for a in ("--set", f"{k}={v}")] + [
    "--bore-ratio", "0", "--first-mode-hz", "32"]


def test_unit_load_is_the_iso_nominal_tooth_root_load():
    from gearpair import GearParams
    from gearpair.geometry import UNIT_LOAD_LIMIT, load_implausibility, unit_load

    # Ft = 2 T / d1 = 2 * 3900 / (0.004 * 25) = 78 kN over b m = 40 mm * 4 mm
    assert unit_load(GearParams(**USER_GEAR), 3900.0) == pytest.approx(487.5)
    assert unit_load(GearParams(), -3900.0) == pytest.approx(7800 / 0.198 / 1200)  # 33 N/mm2
    assert load_implausibility(GearParams(), 3900.0) is None
    msg = load_implausibility(GearParams(**USER_GEAR), 3900.0)
    assert "Ft/(b m) = 487 N/mm2" in msg and f"exceeds {UNIT_LOAD_LIMIT:g} N/mm2" in msg
    # the bound: just below and above 250 N/mm2 for Table 1's gears
    t_limit = UNIT_LOAD_LIMIT * 1e6 * 0.2 * 0.006 * 0.006 * 33 / 2
    assert load_implausibility(GearParams(), 0.999 * t_limit) is None
    assert load_implausibility(GearParams(), 1.001 * t_limit) is not None


def test_simulate_and_scenes_warn_of_an_implausible_torque(tmp_path):
    from gearpair import GearParams
    from gearpair.geometry import GearDataWarning, steel_body
    from gearpair.results import simulate
    from gearpair.scenes import load_scene

    own = steel_body(GearParams(**USER_GEAR), 0.0)
    with pytest.warns(GearDataWarning, match=r"Ft/\(b m\) = 487 N/mm2"):
        simulate(own, t_end=2e-4, torque=3900.0, engine="reference")
    with pytest.warns(GearDataWarning, match=r"Ft/\(b m\) = 487 N/mm2"):  # a ramp's peak
        simulate(own, t_end=2e-4, torque=lambda t: 270.0 + 3630.0 * t / 2e-4, dt=1e-4,
                 engine="reference")
    gear = "\n".join(f"{k} = {v}" for k, v in USER_GEAR.items())
    scene = tmp_path / "own.toml"
    scene.write_text(f"t_end = 2e-4\n[gear]\n{gear}\nbore_ratio = 0\n"
                     "[inputs]\ntorque = {kind = \"ramp\", from = 270.0, to = 3900.0, "
                     "t0 = 0, t1 = 1e-4}\n")
    with pytest.warns(GearDataWarning, match="torque 3900 N.m is implausible"):
        load_scene(scene).run("reference")


def test_cli_warns_of_an_implausible_torque_on_stderr_and_runs(capsys):
    assert main(["simulate", *USER_SET, "--t-end", "0.002", "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["torque_nm"] == 3900.0  # it ran
    lines = [ln for ln in cap.err.splitlines() if "implausible" in ln]
    assert len(lines) == 1 and lines[0].startswith("gearpair: warning: torque 3900 N.m")
    assert main(["simulate", *USER_SET, "--t-end", "0.002", "--torque", "270"]) == 0
    assert "implausible" not in capsys.readouterr().err


def test_sweep_warns_of_its_heaviest_point_before_the_run(no_runs, tmp_path, capsys):
    with pytest.raises(AssertionError, match="run started"):
        main(["sweep", "torque", "270,3900,1000", "--scheduler", "serial", *USER_SET[:10],
              "--out", str(tmp_path / "t")])
    err = capsys.readouterr().err
    assert err.count("implausible") == 1 and "torque 3900 N.m" in err


# -- bench --quick: what it compiles, when, and that it says so ---------------------------------
class _Stop(Exception):
    pass


def test_bench_compiles_the_fmus_engine_beside_its_warm_up_and_before_any_timing(monkeypatch):
    """The FMU's engine (compiled for a portable CPU, about 30 s once per engine change) is
    compiled in a child beside the warm-up, and finished before the first timed section."""
    import threading

    import gearpair.shipped
    from gearpair.bench import QUICK, measure

    events, msgs, release = [], [], threading.Event()

    def ship(package, import_name):
        events.append(("ship", import_name, (Path(package) / "fast").is_dir()))
        release.wait(30)  # finishes only once the warm-up ran: the two overlap
        events.append("ship done")
        return {"cpu_name": "x86-64-v2", "compiled": {"source": "compiled"}}

    def warm_up(progress):
        events.append("warm-up")
        release.set()
        return 0.0

    def references(s, progress):
        events.append("timed")
        raise _Stop

    monkeypatch.setattr(gearpair.shipped, "ship", ship)
    monkeypatch.setattr(measure, "warm_up", warm_up)
    monkeypatch.setattr(measure, "references", references)
    with pytest.raises(_Stop):
        measure.run(QUICK, msgs.append)
    assert ("ship", "_gearpair_fmu", True) in events  # a copy of the package, the FMU's name
    assert events.index("warm-up") < events.index("ship done") < events.index("timed")
    said = "\n".join(msgs)
    assert "compiling the FMU's engine in a child process" in said
    assert "FMU's engine (for x86-64-v2 CPUs): compiled once" in said


_NO_LOAD_AFTER_WARM_UP = r"""
import json, sys
from gearpair import jitcache
from gearpair.bench import QUICK, cost_table, core_step_costs, engine_call_cost, warm_up
warm_up()
before = dict(jitcache.STATS)
core_step_costs(QUICK, {r: [1e-6] for r in ("no_friction", "sliding", "stick_slip")})
engine_call_cost(20)
cost_table(QUICK)
print(json.dumps([before, jitcache.STATS]))
"""


def test_bench_warm_up_loads_every_compiled_path_that_is_timed(tmp_path):
    """After `warm_up` no timed section loads (or compiles) a compiled function: the per-step
    ``advance`` path of the step costs and the ladder was loaded only inside timed runs."""
    import subprocess
    import sys

    pytest.importorskip("numba")
    proc = subprocess.run([sys.executable, "-c", _NO_LOAD_AFTER_WARM_UP], cwd=tmp_path,
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-2000:]
    before, after = json.loads(proc.stdout.strip().splitlines()[-1])
    assert after == before


# -- the suite's expected warnings are filtered where they are expected --------------------------
def test_property_tests_expect_their_table1_body_warnings_and_no_other(tmp_path):
    """With GearDataWarning made an error, the property tests still pass: the one they
    expect (Table 1 bodies with drawn tooth numbers) is filtered in that file, so a new
    warning there would stand out instead of drowning among twenty."""
    import subprocess
    import sys

    pytest.importorskip("hypothesis")
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-W",
         "error::gearpair.geometry.GearDataWarning", str(ROOT / "tests" / "test_properties.py")],
        cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert "warning" not in proc.stdout.splitlines()[-1]


def test_sweep_load_check_leaves_refused_values_to_the_run(no_runs, tmp_path):
    """A value the point refuses (mu = -1) is an `invalid` record of the run, not an error of
    the load check before it."""
    with pytest.raises(AssertionError, match="run started"):
        main(["sweep", "--scheduler", "serial", "--out", str(tmp_path / "m"), "mu", "--",
              "-1,0.02"])


def test_bench_compiles_ahead_under_the_name_the_fmu_imports_its_package():
    import re

    from gearpair.bench.measure import FMU_BUNDLE

    text = (ROOT / "fmu_src" / "GearPair.py").read_text()
    assert re.search(r'^BUNDLE = "([^"]+)"', text, re.M).group(1) == FMU_BUNDLE
