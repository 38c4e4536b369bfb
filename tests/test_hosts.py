"""The FMU in other co-simulation hosts: libcosimpy and ecospy (two instances in one process
each), the `ecos` command-line host and a small C host (non-Python, run with an empty
environment: the FMU loads the Python recorded in it).

Every host's outputs are compared with the same case run by fmpy (or, for the C host, with
the reference engine stepped over the same communication points): ``|host - fmpy| <=
K * rtol * scale`` with ``K = 1000`` as in test_fmu_harness.py. Hosts step on their own time
grids (libcosim in integer nanoseconds, ecos by accumulating ``t += h``), which differ from
fmpy's ``n * h`` in the last bit; that moves the solution by up to about 1e-6 of the scale at
``rtol = 1e-6`` and 1e-8 of it at ``rtol = 1e-8``.

A host that cannot be installed or run here is skipped with the reason;
``scripts/setup.sh`` installs libcosimpy, ecospy and libtbb12 so that CI runs them all.
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import signal
import stat
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")

ROOT = Path(__file__).resolve().parents[1]
HOSTS = ROOT / "examples" / "hosts"
sys.path.insert(0, str(HOSTS))

from hosts_common import INT_OUTPUTS, OUTPUTS, run_fmpy, value_references  # noqa: E402

pytestmark = pytest.mark.fmu

RPM = 2.0 * math.pi / 60.0
K = 1000.0
RTOL = 1e-8
H = 1e-4
N_STEPS = 20
# two instances that differ in a parameter and an input
CASES = {
    "g1": {"rtol": RTOL},
    "g2": {"rtol": RTOL, "torque": 2500.0, "speed": 300 * RPM, "mu": 0.05},
}


def assert_close(host: dict[str, np.ndarray], ref: dict[str, np.ndarray], rtol: float,
                 names=OUTPUTS, label: str = "") -> dict[str, float]:
    errors = {}
    for name in names:
        scale = max(float(np.max(np.abs(ref[name]))), 1e-300)
        err = float(np.max(np.abs(np.asarray(host[name]) - ref[name]))) / scale
        errors[name] = err
        assert err <= K * rtol, (label, name, err)
    return errors


def _import_or_skip(module: str, hint: str):
    try:
        return pytest.importorskip(module)
    except OSError as e:  # the wheel imports, but its native library does not load
        pytest.skip(f"{module} cannot load its native library ({e}); {hint}")


def _host_module(name: str):
    """Load examples/hosts/<name>.py by path: examples/driveline has modules of the same
    names, and which one a bare import finds depends on the order tests were collected."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"hosts_{name}", HOSTS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# -- Python hosts ------------------------------------------------------------------------------
def test_libcosimpy_two_instances(fmu_path):
    _import_or_skip("libcosimpy", "pip install libcosimpy")
    run_libcosim = _host_module("run_libcosim")

    res = run_libcosim.run(str(fmu_path), CASES, h_ns=round(H * 1e9), n_steps=N_STEPS)
    for name, case in CASES.items():
        ref = run_fmpy(str(fmu_path), case, H, N_STEPS)
        assert_close(res[name], ref, RTOL, label=f"libcosim {name}")
        np.testing.assert_array_equal(res[name]["contact_state"], ref["contact_state"])
    assert not np.allclose(res["g1"]["dte"], res["g2"]["dte"])  # the instances are separate


def test_ecospy_two_instances(fmu_path):
    _import_or_skip("ecospy", "it needs the Debian package libtbb12 (scripts/setup.sh)")
    run_ecospy = _host_module("run_ecospy")

    res = run_ecospy.run(str(fmu_path), CASES, h=H, n_steps=N_STEPS)
    for name, case in CASES.items():
        ref = run_fmpy(str(fmu_path), case, H, N_STEPS)
        assert_close(res[name], ref, RTOL, label=f"ecospy {name}")
        np.testing.assert_array_equal(res[name]["contact_state"], ref["contact_state"])
    assert not np.allclose(res["g1"]["dte"], res["g2"]["dte"])


# -- non-Python hosts --------------------------------------------------------------------------
def native_env() -> dict[str, str]:
    """Environment of a non-Python host: as bare as a launcher's (`env -i PATH=/usr/bin:/bin
    HOME=$HOME`); the FMU loads the Python recorded in it by itself."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        pytest.skip("this Python has no shared libpython: a C host cannot run the FMU built "
                    "with it")
    return {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}


def _signal_name(rc: int) -> str:
    try:
        return signal.Signals(-rc).name
    except ValueError:
        return str(rc)


def compile_c_host(source: Path, exe: Path) -> Path:
    """Build a C host with gcc against fmpy's FMI 2 headers and examples/hosts/fmu_dl.h
    (skip without either)."""
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        pytest.skip("no C compiler")
    include = Path(fmpy.__file__).parent / "c-code"
    if not (include / "fmi2Functions.h").is_file():
        pytest.skip(f"fmpy ships no FMI 2 headers in {include}")
    subprocess.run([gcc, "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror", f"-I{include}",
                    f"-I{HOSTS}", "-o", str(exe), str(source), "-ldl", "-lm", "-lpthread"],
                   check=True)
    return exe


@pytest.fixture(scope="module")
def c_host(tmp_path_factory) -> Path:
    """examples/hosts/fmi2_host.c, built."""
    return compile_c_host(HOSTS / "fmi2_host.c", tmp_path_factory.mktemp("c_host") / "fmi2_host")


def test_c_host_variable_steps(fmu_path, tmp_path, c_host):
    """A dlopen host in C with step sizes that change from call to call, returning normally
    from main (exit status 0); compared with the reference engine over the same points."""
    env = native_env()
    exe = c_host
    unzipdir = Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "unzip")))
    md = fmpy.read_model_description(str(fmu_path))
    vr = value_references(str(fmu_path))
    steps = (1e-6, 1e-5, 3e-4, 1e-3, 4e-5, 6.49e-4)
    n = 2 * len(steps)
    cmd = [str(exe), str(unzipdir), md.coSimulation.modelIdentifier, md.guid,
           ",".join(repr(h) for h in steps), str(n),
           "-r", f"{vr['rtol'][0]}={RTOL!r}", "-r", f"{vr['torque'][0]}=2500",
           "-o", ",".join(str(vr[o][0]) for o in OUTPUTS),
           "-n", ",".join(str(vr[o][0]) for o in INT_OUTPUTS)]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"rc {_signal_name(proc.returncode)}: {proc.stderr[-2000:]}"
    rows = np.array([[float(x) for x in line.split(",")] for line in proc.stdout.split()])
    assert rows.shape == (n + 1, 1 + len(OUTPUTS) + len(INT_OUTPUTS))
    host = {o: rows[1:, 1 + j] for j, o in enumerate(OUTPUTS + INT_OUTPUTS)}
    from gearpair import Effects, GearParams
    from gearpair.reference import ReferenceEngine

    eng = ReferenceEngine(GearParams(), Effects(), rtol=RTOL)
    eng.reset(0.0, 2500.0, 100 * RPM, static=True)
    t, ref = 0.0, {o: [] for o in OUTPUTS + INT_OUTPUTS}
    for k in range(n):
        t += steps[k % len(steps)]
        eng.advance(t, 2500.0, 100 * RPM)
        out = eng.outputs()
        for o in OUTPUTS + INT_OUTPUTS:
            ref[o].append(float(getattr(out, o)))
    ref = {o: np.array(v) for o, v in ref.items()}
    np.testing.assert_array_equal(rows[1:, 0], np.cumsum([steps[k % len(steps)]
                                                          for k in range(n)]))
    assert_close(host, ref, RTOL, label="C host")
    np.testing.assert_array_equal(host["contact_state"], ref["contact_state"])


@pytest.mark.parametrize("unload", [0, 1])
def test_c_host_exits_cleanly(fmu_path, tmp_path, c_host, unload):
    """Exit status 0 in three runs, returning from main with and without dlclose of the
    FMU's library after fmi2FreeInstance (the interpreter is never finalized there)."""
    env = native_env()
    unzipdir = Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "unzip")))
    md = fmpy.read_model_description(str(fmu_path))
    vr = value_references(str(fmu_path))
    for _ in range(3):
        proc = subprocess.run([str(c_host), str(unzipdir), md.coSimulation.modelIdentifier,
                               md.guid, "1e-4", "3", "-o", str(vr["mesh_force"][0]),
                               "-d", str(unload)],
                              env=env, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"rc {_signal_name(proc.returncode)}: {proc.stderr[-2000:]}"
        assert len(proc.stdout.split()) == 4 and not proc.stderr, proc.stderr


_PY_HOST = """
import sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
fmu, mode = sys.argv[1], sys.argv[2]
md = read_model_description(fmu)
d = extract(fmu)
vr = {v.name: v.valueReference for v in md.modelVariables}
def make(name):
    s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier="GearPair",
                  instanceName=name)
    s.instantiate(); s.setupExperiment(startTime=0.0); s.setReal([vr["rtol"]], [1e-6])
    s.enterInitializationMode(); s.exitInitializationMode()
    return s
def run(s):
    for k in range(3):
        s.doStep(k * 1e-4, 1e-4)
    return s.getReal([vr["mesh_force"]])[0]
if mode == "reinstantiate":
    a = make("a"); x = run(a); a.terminate(); a.freeInstance()
    b = make("b"); y = run(b); b.terminate(); b.freeInstance()
    print(x == y)
else:
    a, b = make("a"), make("b")
    b.setReal([vr["torque"]], [2500.0])
    x, y = run(a), run(b)
    a.terminate(); b.terminate(); a.freeInstance(); b.freeInstance()
    print(x != y)
"""


@pytest.mark.parametrize("mode", ["reinstantiate", "two"])
def test_python_host_instances_exit_cleanly(fmu_path, tmp_path, mode):
    """A Python host that frees one instance and instantiates another, and one with two
    live instances: right results and exit status 0, nothing on stderr."""
    for _ in range(2):
        proc = subprocess.run([sys.executable, "-c", _PY_HOST, str(fmu_path), mode],
                              cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"rc {_signal_name(proc.returncode)}: {proc.stderr[-2000:]}"
        assert proc.stdout.split() == ["True"] and not proc.stderr, proc.stderr


def test_fmpy_command_line_exits_cleanly_and_reports_errors(fmu_path, tmp_path):
    """`fmpy simulate` exits 0; with an invalid start value it prints the FMU's message
    without --debug-logging and exits non-zero."""
    fmpy_cli = Path(sys.executable).parent / "fmpy"
    if not fmpy_cli.is_file():
        pytest.skip("no fmpy command line next to this Python")
    for _ in range(2):
        proc = subprocess.run([str(fmpy_cli), "simulate", str(fmu_path), "--stop-time", "5e-4",
                               "--output-interval", "1e-4", "--output-file", "out.csv"],
                              cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"rc {_signal_name(proc.returncode)}: {proc.stderr[-2000:]}"
    proc = subprocess.run([str(fmpy_cli), "simulate", str(fmu_path), "--stop-time", "5e-4",
                           "--start-values", "mu", "-1"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.returncode  # fmpy's status for an exception
    out = proc.stdout + proc.stderr
    assert "mu = -1 is out of range; allowed [0, 1]" in out, out[-2000:]


def test_ecos_command_line(fmu_path, tmp_path):
    """The `ecos` binary shipped in the ecospy wheel, with an empty environment."""
    ecospy = _import_or_skip("ecospy", "it needs the Debian package libtbb12")
    src = Path(ecospy.__file__).parent / "binaries"
    if not (src / "ecos").is_file():
        pytest.skip(f"no ecos binary in {src}")
    env = native_env()
    bindir = tmp_path / "bin"
    bindir.mkdir()
    for f in ("ecos", "proxyfmu", "libecosc.so"):  # the wheel installs them without +x
        if (src / f).is_file():
            shutil.copy2(src / f, bindir / f)
            (bindir / f).chmod((bindir / f).stat().st_mode | stat.S_IXUSR)
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    # at least 10 steps: with fewer, ecos 0.7.2 dies of a division by zero in its progress
    # report (SIGFPE)
    proc = subprocess.run([str(bindir / "ecos"), "simulate", "--path", str(fmu_path),
                           "--stepSize", repr(H), "--stopTime", repr(N_STEPS * H)],
                          cwd=run_dir, env=env, capture_output=True, text=True, timeout=300)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"rc {_signal_name(proc.returncode)}: {log[-3000:]}"
    assert "Wrote CSV data" in log, log[-3000:]
    files = list(run_dir.glob("*.csv"))
    assert len(files) == 1, log[-3000:]
    with files[0].open() as fh:
        reader = csv.reader(fh, skipinitialspace=True)
        header = next(reader)
        data = np.array([[float(x) for x in row] for row in reader if row])
    col = {h.split("::")[-1].split("[")[0].strip(): j for j, h in enumerate(header)}
    time = data[:, col["time"]]
    # rows at 0, h, ..., (N - 1) h: ecos stops one step short of stopTime
    assert time[0] == 0.0 and len(time) >= N_STEPS
    ref = run_fmpy(str(fmu_path), {}, H, len(time) - 1)
    # ecos prints 6 decimals: compare the signals that are large in SI units
    host = {o: data[1:, col[o]] for o in ("mesh_force", "gear1_speed", "gear2_speed")}
    np.testing.assert_allclose(time[1:], H * np.arange(1, len(time)), rtol=1e-12)
    assert_close(host, ref, RTOL, names=tuple(host), label="ecos")
    np.testing.assert_array_equal(data[1:, col["contact_state"]], ref["contact_state"])
