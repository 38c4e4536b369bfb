"""GearPair.fmu where there is no Python: a root folder that holds only the C host, the
extracted FMU and the libraries ``ldd`` lists for them, entered with ``chroot`` (as root) or
an unprivileged user namespace (``unshare -r``). No python can run in there; the default
engine (compiled into the FMU's binary) runs the scenes bit for bit as the Python API's fast
engine, and the reference engine, which needs Python, fails with a clear error, no crash.
The fuzz test's C host and OMSimulator's command line (with its own libraries) run in there
too."""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")

from test_fmu_fuzz import FUZZ_C, fuzz_spec  # noqa: E402
from test_hosts import compile_c_host  # noqa: E402
from test_omsimulator import _home as omsimulator_home  # noqa: E402

pytestmark = pytest.mark.fmu

ROOT = Path(__file__).resolve().parents[1]
RPM = 2.0 * math.pi / 60.0

# scene -> (FMU start values, Python API GearParams fields, Effects fields)
SCENES = {
    "stick-slip": ({}, {}, {}),
    "geometry": ({"module": 0.004, "z1": 25, "z2": 61}, {"module": 0.004, "z1": 25, "z2": 61},
                 {}),
    "constant stiffness": ({"stiffness_model": 1}, {}, {"stiffness": "constant"}),
    "rectangular stiffness": ({"stiffness_model": 2, "friction_law": 1}, {},
                              {"stiffness": "rectangular", "friction": "nominal"}),
    "backlash": ({"backlash": 5e-5, "friction_law": 2}, {},
                 {"backlash": 5e-5, "friction": "regularized"}),
}
STEPS, DT = 200, 1e-4


def _bring(root: Path, *files: Path) -> None:
    """The shared libraries ``ldd`` lists for ``files``, copied into ``root`` at their
    paths."""
    for lib in _libraries(*files):
        dest = root / lib.lstrip("/")
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(os.path.realpath(lib), dest)


def _libraries(*files: Path) -> set[str]:
    """The shared libraries ``ldd`` lists for ``files`` (absolute paths)."""
    out = set()
    for f in files:
        r = subprocess.run(["ldd", str(f)], capture_output=True, text=True, check=True)
        out |= set(re.findall(r"(/\S+\.so[.\d]*)", r.stdout))
    return out


def _enter() -> list[str] | None:
    """The command prefix that changes the root (before the root folder), or None."""
    chroot, unshare = shutil.which("chroot"), shutil.which("unshare")
    if chroot and os.geteuid() == 0:
        return [chroot]
    if chroot and unshare:
        probe = subprocess.run([unshare, "-r", "true"], capture_output=True)
        if probe.returncode == 0:
            return [unshare, "-r", chroot]
    return None


@pytest.fixture(scope="module")
def jail(fmu_path, tmp_path_factory) -> dict:
    enter = _enter()
    if enter is None:
        pytest.skip("neither root nor unprivileged user namespaces: no chroot here")
    base = tmp_path_factory.mktemp("jail")
    host = compile_c_host(ROOT / "examples" / "hosts" / "fmi2_host.c", base / "fmi2_host")
    root = base / "root"
    (root / "bin").mkdir(parents=True)
    shutil.copy(host, root / "bin" / "fmi2_host")
    fmpy.extract(str(fmu_path), unzipdir=str(root / "fmu"))
    so = root / "fmu" / "binaries" / "linux64" / "GearPair.so"
    _bring(root, host, so)
    shutil.copy(fmu_path, root / "GearPair.fmu")
    (root / "tmp").mkdir()
    md = fmpy.read_model_description(str(fmu_path))
    return {"root": root, "enter": enter, "md": md, "base": base,
            "vr": {v.name: v.valueReference for v in md.modelVariables},
            "types": {v.name: v.type for v in md.modelVariables}}


def _api_run(gear: dict, effects: dict, steps: int, dt: float) -> list[dict]:
    """The Python API's fast engine at the default point: the step record after each step,
    stepped as a master does (t += dt)."""
    from gearpair import Effects, GearParams
    from gearpair import stepblock as sb
    from gearpair.fast import FastEngine

    eng = FastEngine(GearParams(**gear), Effects(**effects), rtol=1e-8)
    eng.reset(0.0, 3900.0, 100 * RPM)
    t, out = 0.0, []
    for _ in range(steps):
        eng.advance(t + dt, 3900.0, 100 * RPM)
        t += dt
        out.append({n: float(eng.block[sb.X_REC + k]) for k, n in enumerate(sb.STEP_RECORD)})
    return out


def _run(jail: dict, start: dict) -> subprocess.CompletedProcess:
    vr, types = jail["vr"], jail["types"]
    args = []
    for name, value in start.items():
        args += ["-i" if types[name] == "Integer" else "-r", f"{vr[name]}={value!r}"]
    cmd = [*jail["enter"], str(jail["root"]), "/bin/fmi2_host", "/fmu", "GearPair",
           jail["md"].guid, repr(DT), str(STEPS),
           "-o", f"{vr['dte']},{vr['mesh_force']},{vr['friction_force']}",
           "-n", str(vr["contact_state"]), *args]
    return subprocess.run(cmd, env={"PATH": "/bin"}, capture_output=True, text=True,
                          timeout=120)


def test_nothing_of_python_is_in_the_root(jail):
    root = jail["root"]
    # the FMU's resources name the Python for the reference engine (python.txt, a script);
    # nothing that could run Python is there
    found = [p for p in root.rglob("*") if "python" in p.name.lower()
             and p.suffix not in (".py", ".txt") and "pythonfmu" not in p.name]
    assert found == []
    r = subprocess.run([*jail["enter"], str(root), "/usr/bin/python3", "-c", "1"],
                       capture_output=True, text=True)
    assert r.returncode != 0  # no python runs in there


@pytest.mark.filterwarnings("ignore::gearpair.geometry.GearDataWarning")  # Table 1 bodies
@pytest.mark.parametrize("scene", SCENES)
def test_scenes_run_bit_for_bit_as_the_python_api(jail, scene):
    start, gear, effects = SCENES[scene]
    proc = _run(jail, start)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [line.split(",") for line in proc.stdout.split()]
    assert len(rows) == STEPS + 1
    names = ("dte", "mesh_force", "friction_force", "contact_state")
    for k, (row, want) in enumerate(zip(rows[1:], _api_run(gear, effects, STEPS, DT),
                                        strict=True)):
        got = [float(x) for x in row[1:]]
        assert got == [want[n] for n in names], (scene, k, got, want)
    assert "Python" not in proc.stderr


def test_the_reference_engine_says_it_needs_python(jail):
    proc = _run(jail, {"engine": 1})
    assert proc.returncode == 1, proc.stderr[-2000:]
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("[host|3|")]
    assert len(errors) == 1 and "engine = 1 (reference) needs Python" in errors[0], \
        proc.stderr


def test_the_fuzz_test_runs_in_there(jail, tmp_path):
    """The FMI call-sequence fuzzer (tests/test_fmu_fuzz.py) against the FMU in the root
    with nothing else: no fmi2Fatal, every refusal logged, exit 0."""
    root = jail["root"]
    fuzzer = compile_c_host(FUZZ_C, tmp_path / "fmi2_fuzz")
    shutil.copy(fuzzer, root / "bin" / "fmi2_fuzz")
    _bring(root, fuzzer)
    (root / "spec.txt").write_text(fuzz_spec(jail["md"]))
    n = 200
    proc = subprocess.run([*jail["enter"], str(root), "/bin/fmi2_fuzz", "/fmu", "GearPair",
                           jail["md"].guid, "/spec.txt", "7", str(n)], env={"PATH": "/bin"},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = proc.stdout.split("\n")[0]
    assert summary.startswith(f"ops {n};") and "fatal 0" in summary, proc.stdout
    assert "error 0" not in summary


def test_omsimulator_runs_it_in_there(jail):
    """OMSimulator's command line, with the libraries it needs, simulates the FMU file in
    the root: exit 0, no warning, and the outputs of the Python API (OMSimulator writes 12
    significant digits)."""
    home = omsimulator_home()
    if home is None:
        pytest.skip("OMSimulator not found: set OMSIMULATOR_HOME to its folder")
    root = jail["root"]
    exe = home / "bin" / "OMSimulator"
    (root / "oms" / "bin").mkdir(parents=True, exist_ok=True)
    shutil.copy(exe, root / "oms" / "bin" / "OMSimulator")
    _bring(root, exe)
    proc = subprocess.run([*jail["enter"], str(root), "/oms/bin/OMSimulator", "/GearPair.fmu",
                           "--stopTime=0.002", "--stepSize=1e-4", "--resultFile=/out.csv"],
                          env={"PATH": "/bin"}, capture_output=True, text=True, timeout=120,
                          cwd="/")
    log = proc.stdout + proc.stderr
    if proc.returncode != 0 and "libicu" in log:
        pytest.skip("OMSimulator needs Debian's libicu72 (scripts/setup.sh installs it)")
    assert proc.returncode == 0, log[-3000:]
    assert not [ln for ln in log.splitlines() if re.match(r"\s*(warning|error)\b", ln, re.I)]
    lines = (root / "out.csv").read_text().splitlines()
    header = [h.strip('"') for h in lines[0].split(",")]
    rows = [dict(zip(header, map(float, ln.split(",")), strict=True)) for ln in lines[1:]]
    last = {}
    for r in rows:  # OMSimulator writes some times twice: the last row of each
        last[r["time"]] = r
    api = _api_run({}, {}, 20, 1e-4)
    for k, want in enumerate(api, start=1):
        got = last[round(k * 1e-4, 12)] if round(k * 1e-4, 12) in last else \
            min(last.values(), key=lambda r, k=k: abs(r["time"] - k * 1e-4))
        for name in ("dte", "mesh_force", "friction_force"):
            assert got[name] == pytest.approx(want[name], rel=1e-10, abs=1e-14), (k, name)
