"""GearPair.fmu in OMSimulator (OpenModelica's co-simulation master), a C++ host.

OMSimulator is found through the environment variable ``OMSIMULATOR_HOME`` (its folder with
``bin/OMSimulator`` and ``lib/``) or, failing that, in ``../shared/tools/omsimulator``
beside the repository; without it (or when it cannot start, e.g. without Debian's
``libicu72``) every test here is skipped with the reason. The command line runs with an
empty environment (`env -i PATH=/usr/bin:/bin HOME=$HOME`), as from a launcher: the FMU
loads the Python recorded in it.

Checked: repeated runs exit 0 without a warning; results equal fmpy's at rtol 1e-10; an
invalid start value stops the run at initialization with the FMU's message; its Python API
with and without deleting the model; GearPair in a feedback loop with the driveline's load
(and motor) FMUs and two GearPair instances coupled both ways run without an algebraic loop
(the outputs declare no direct dependency on inputs).
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

pytestmark = pytest.mark.fmu

ROOT = Path(__file__).resolve().parents[1]
H = 1e-4  # s, communication step
N = 20  # steps of the comparison runs


def _home() -> Path | None:
    given = os.environ.get("OMSIMULATOR_HOME")
    for cand in ([Path(given)] if given else []) + [ROOT.parent / "shared" / "tools" /
                                                     "omsimulator"]:
        if (cand / "bin" / "OMSimulator").is_file():
            return cand
    return None


def clean_env() -> dict[str, str]:
    return {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}


@pytest.fixture(scope="module")
def oms() -> Path:
    """OMSimulator's folder, checked to start (else skip with the reason)."""
    home = _home()
    if home is None:
        pytest.skip("OMSimulator not found: set OMSIMULATOR_HOME to its folder")
    r = subprocess.run([str(home / "bin" / "OMSimulator"), "--version"], env=clean_env(),
                       capture_output=True, text=True, timeout=60)
    if r.returncode != 0:
        pytest.skip(f"OMSimulator does not start ({(r.stdout + r.stderr).strip()[-300:]}); "
                    "it needs Debian's libicu72 (scripts/setup.sh installs it)")
    return home


def run(oms: Path, args: list[str], cwd: Path) -> tuple[int, str]:
    """OMSimulator's command line in ``cwd`` with an empty environment: (status, output)."""
    cwd.mkdir(parents=True, exist_ok=True)
    r = subprocess.run([str(oms / "bin" / "OMSimulator"), *args], cwd=cwd, env=clean_env(),
                       capture_output=True, text=True, timeout=300)
    return r.returncode, r.stdout + r.stderr


def problems(log: str) -> list[str]:
    """OMSimulator's warning and error lines, and algebraic-loop reports."""
    return [ln for ln in log.splitlines()
            if re.match(r"\s*(warning|error)\b", ln, re.I) or "alg. loop" in ln.lower()
            or "algebraic loop" in ln.lower()]


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """OMSimulator's result file, its rows written twice (a known behaviour) once each."""
    with path.open() as fh:
        header = [h.strip().strip('"') for h in fh.readline().split(",")]
        rows = [[float(x) for x in line.split(",")] for line in fh if line.strip()]
    data = np.array(rows)
    keep = np.r_[data[1:, 0] != data[:-1, 0], True]  # the last row of each time
    return {h: data[keep, j] for j, h in enumerate(header)}


def lua(path: Path, body: str) -> Path:
    path.write_text('oms_setTempDirectory("./tmp")\n' + body)
    return path


def _value(v) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else repr(v)


def _setter(v) -> str:
    return "oms_setBoolean" if isinstance(v, bool) else \
        "oms_setInteger" if isinstance(v, int) else "oms_setReal"


def model_script(fmus: dict[str, Path], starts: dict[str, dict], connections, stop: float,
                 result: str) -> str:
    """A Lua script: one weakly coupled system of the FMUs, start values, connections; it
    prints the status of instantiate, initialize, simulate, terminate and delete (0 = ok)."""
    lines = ['oms_setCommandLineOption("--dumpAlgLoops=true")', 'oms_newModel("m")',
             'oms_addSystem("m.root", oms_system_wc)']
    lines += [f'oms_addSubModel("m.root.{n}", "{p}")' for n, p in fmus.items()]
    lines += [f'{_setter(v)}("m.root.{n}.{k}", {_value(v)})'
              for n, values in starts.items() for k, v in values.items()]
    lines += [f'oms_addConnection("m.root.{a}.{x}", "m.root.{b}.{y}")'
              for a, x, b, y in connections]
    lines += [f'oms_setResultFile("m", "{result}")', f'oms_setStopTime("m", {stop!r})',
              f'oms_setFixedStepSize("m.root", {H!r})']
    lines += [f'print("{call}", oms_{call}("m"))'
              for call in ("instantiate", "initialize", "simulate", "terminate", "delete")]
    return "\n".join(lines) + "\n"


def statuses(log: str) -> dict[str, int]:
    return {m.group(1): int(m.group(2)) for m in
            re.finditer(r"^(instantiate|initialize|simulate|terminate|delete)\s+(\d+)", log,
                        re.M)}


@pytest.mark.slow
def test_twenty_runs_exit_0_without_a_warning(oms, fmu_path, tmp_path):
    """The command line simulating the FMU alone, 20 times (two at a time): exit status 0,
    no warning or error, results written."""
    def one(k: int):
        where = tmp_path / f"run{k}"
        return where, run(oms, [str(fmu_path), "--stopTime=0.002", f"--stepSize={H!r}",
                                "--resultFile=out.csv"], where)

    with ThreadPoolExecutor(2) as pool:
        for where, (rc, log) in pool.map(one, range(20)):
            assert rc == 0, log[-3000:]
            assert not problems(log), problems(log)
            assert len(read_csv(where / "out.csv")["time"]) == N + 1


def test_results_equal_fmpys(oms, fmu_path, tmp_path):
    """A start value (rtol = 1e-10) through oms_setReal, 20 steps: every output equal to
    fmpy's to 1e-9 of its scale."""
    script = lua(tmp_path / "run.lua", model_script(
        {"gp": fmu_path}, {"gp": {"rtol": 1e-10}}, (), N * H, "out.csv"))
    rc, log = run(oms, [script.name], tmp_path)
    assert rc == 0 and set(statuses(log).values()) == {0}, log[-3000:]
    assert not problems(log), problems(log)
    got = read_csv(tmp_path / "out.csv")
    md = fmpy.read_model_description(str(fmu_path))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    ref = fmpy.simulate_fmu(str(fmu_path), stop_time=N * H, output_interval=H,
                            start_values={"rtol": 1e-10}, output=outputs)
    np.testing.assert_allclose(got["time"], ref["time"], rtol=0, atol=1e-12)
    for name in outputs:
        a, b = got[f"m.root.gp.{name}"], np.asarray(ref[name], dtype=float)
        scale = max(float(np.max(np.abs(b))), 1e-300)
        assert float(np.max(np.abs(a - b))) <= 1e-9 * scale, name


@pytest.mark.parametrize("start, words", [
    ({"mu": -1.0}, "mu = -1 was refused at fmi2SetReal; set a valid value or leave it unset"),
    ({"rtol": 0.5}, "rtol = 0.5 was refused at fmi2SetReal"),
])
def test_an_invalid_start_value_stops_the_run_at_initialization(oms, fmu_path, tmp_path,
                                                               start, words):
    """OMSimulator ignores the status of fmi2SetReal; the FMU remembers the refused value and
    refuses fmi2ExitInitializationMode, so oms_initialize and oms_simulate return error (3)
    and the FMU's messages are shown."""
    script = lua(tmp_path / "run.lua", model_script(
        {"gp": fmu_path}, {"gp": start}, (), N * H, "out.csv"))
    rc, log = run(oms, [script.name], tmp_path)
    st = statuses(log)
    assert st["instantiate"] == 0 and st["initialize"] == 3 and st["simulate"] == 3, log
    assert words in log and "is out of range" in log, log[-3000:]


_PY_API = """
import importlib.util, sys
home, fmu, mode = sys.argv[1:4]
# the C API wrapper of OMSimulator's Python package, loaded alone (the package itself also
# needs lxml and requests, which this environment does not have to have)
spec = importlib.util.spec_from_file_location("oms_capi", home + "/lib/OMSimulator/capi.py")
capi = importlib.util.module_from_spec(spec)
spec.loader.exec_module(capi)
oms = capi.capi()
st = [oms.setTempDirectory("./tmp"), oms.newModel("m"), oms.addSystem("m.root", 1),
      oms.addSubModel("m.root.gp", fmu), oms.setReal("m.root.gp.rtol", 1e-8),
      oms.setResultFile("m", "out.csv"), oms.setStopTime("m", 0.002),
      oms.setFixedStepSize("m.root", 1e-4), oms.instantiate("m"), oms.initialize("m"),
      oms.simulate("m")]
force, ok = oms.getReal("m.root.gp.mesh_force")
if mode == "delete":
    st += [oms.terminate("m"), oms.delete("m")]
print(repr(force), all(s.value == 0 for s in st + [ok]), flush=True)
# "keep": the script ends with the model alive; OMSimulator frees it from a static
# destructor after Python has finalized
"""


@pytest.mark.parametrize("mode", ["delete", "keep"])
def test_python_api_with_and_without_delete(oms, fmu_path, tmp_path, mode):
    """OMSimulator's Python API in this environment's Python: every call ok, and exit
    status 0 also when the script leaves its model alive (then OMSimulator's destructor
    calls fmi2Terminate and fmi2FreeInstance after Python has finalized, which the FMU's C
    layer answers without entering Python)."""
    r = subprocess.run([sys.executable, "-c", _PY_API, str(oms), str(fmu_path), mode],
                       cwd=tmp_path, env=clean_env(), capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    force, ok = r.stdout.splitlines()[-1].split()  # after OMSimulator's info lines
    assert ok == "True" and math.isfinite(float(force)) and float(force) > 0, r.stdout
    assert not problems(r.stdout + r.stderr), r.stdout + r.stderr


@pytest.fixture(scope="module")
def driveline(fmu_path, tmp_path_factory):
    """Motor.fmu and Load.fmu of the driveline example (quick variant), and its module."""
    sys.path.insert(0, str(ROOT / "examples" / "driveline"))
    import driveline_system as ds

    out = tmp_path_factory.mktemp("oms_driveline")
    ds.sibling("build").build(out, overrides=ds.QUICK, gearpair_fmu=fmu_path,
                              stop_time=ds.QUICK_STOP_TIME, step=H)
    return out, ds


def test_driveline_feedback_loop_has_no_algebraic_loop(oms, driveline, tmp_path):
    """Motor -> GearPair -> Load with the torques fed back (GearPair.load_speed from
    Load.speed): no algebraic loop reported, no warning, and the system settles at the
    driveline's operating point (within the mesh losses the estimate neglects)."""
    out, ds = driveline
    params = ds.merged_parameters(ds.QUICK)
    fmus = {name: out / f for name, f in ds.FMU_FILES.items()}
    stop = 0.15  # s: settled (time constant 14 ms), before the load step at 0.2 s
    script = lua(tmp_path / "driveline.lua", model_script(
        fmus, params, ds.CONNECTIONS, stop, "out.csv"))
    rc, log = run(oms, [script.name], tmp_path)
    assert rc == 0 and set(statuses(log).values()) == {0}, log[-3000:]
    assert not problems(log), problems(log)
    got = read_csv(tmp_path / "out.csv")
    expect = ds.steady_state(params)
    assert got["time"][-1] == pytest.approx(stop)
    motor = got["m.root.Motor.speed"][-1]
    load = got["m.root.Load.speed"][-1]
    assert motor == pytest.approx(expect["motor_speed"], rel=0.02)
    assert load == pytest.approx(expect["load_speed"], rel=0.02)
    # the loop is closed: GearPair's load_speed input follows Load.speed
    np.testing.assert_allclose(got["m.root.GearPair.load_speed"][-10:],
                               got["m.root.Load.speed"][-10:], rtol=1e-3)


def test_two_instances_coupled_both_ways(oms, fmu_path, tmp_path):
    """Two GearPair instances in one system, gp1's gear 2 driving gp2 and gp2's gear 2
    speed fed back as gp1's load speed: no algebraic loop, every call ok, and the two
    instances compute apart (gp2 runs at gp1's output speed)."""
    starts = {"gp1": {"rtol": 1e-6, "load_speed_input": True},
              "gp2": {"rtol": 1e-6, "torque": 2500.0}}
    conns = (("gp1", "gear2_speed", "gp2", "speed"), ("gp2", "gear2_speed", "gp1", "load_speed"))
    script = lua(tmp_path / "two.lua", model_script(
        {"gp1": fmu_path, "gp2": fmu_path}, starts, conns, N * H, "out.csv"))
    rc, log = run(oms, [script.name], tmp_path)
    assert rc == 0 and set(statuses(log).values()) == {0}, log[-3000:]
    assert not problems(log), problems(log)
    got = read_csv(tmp_path / "out.csv")
    g1, g2 = got["m.root.gp1.mesh_force"], got["m.root.gp2.mesh_force"]
    assert np.all(np.isfinite(g1)) and np.all(np.isfinite(g2))
    assert not np.allclose(g1, g2)
    # after each communication point's exchange (the last row of each time), the inputs
    # hold the other instance's outputs
    np.testing.assert_array_equal(got["m.root.gp2.speed"][1:], got["m.root.gp1.gear2_speed"][1:])
    np.testing.assert_array_equal(got["m.root.gp1.load_speed"][1:],
                                  got["m.root.gp2.gear2_speed"][1:])
