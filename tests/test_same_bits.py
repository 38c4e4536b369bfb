"""Same bits on every machine: results do not depend on the BLAS kernel, the C library's math
paths, the CPU target numba compiles for, or the number of BLAS threads.

Subprocesses run a representative set of golden cases (each friction law, DP5 and DOP853,
the exact propagator, backlash, mesh resonance with impacts) through the Python API, and the
FMU through fmpy and through the C host, under other OpenBLAS kernels, glibc told to take its
paths for CPUs without AVX2/FMA/AVX-512, and 1 or 2 BLAS threads. The Python API runs code
numba compiled for this CPU; the FMU runs the engine it ships, compiled for x86-64-v2
(`gearpair.shipped`): so the FMU's runs against the golden file compare the two CPU targets.
Every result must equal the golden file and the others bit for bit.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "golden"))
import make_golden  # noqa: E402

CASES = ("effects/friction_off", "effects/friction_nominal", "effects/friction_regularized",
         "effects/friction_stick_slip", "effects/friction_stick_slip_dp5",
         "effects/rectangular_off_lti_True", "effects/friction_stick_slip_backlash",
         "hard/resonance_backlash_5000rpm")
RESONANCE = "hard/resonance_backlash_5000rpm"
FMU_STEPS = 200  # 1e-4 s steps: the golden resonance case's 20 ms, with its impacts
NO_AVX = "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F"
ENVIRONMENTS = {
    "OpenBLAS Prescott": {"OPENBLAS_CORETYPE": "Prescott"},
    "OpenBLAS Sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge"},
    "OpenBLAS Haswell, 2 threads": {"OPENBLAS_CORETYPE": "Haswell", "OPENBLAS_NUM_THREADS": "2"},
    "OpenBLAS Zen, 1 thread": {"OPENBLAS_CORETYPE": "Zen", "OPENBLAS_NUM_THREADS": "1"},
    "OpenBLAS SkylakeX": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "libm without AVX2, FMA, AVX-512": {"GLIBC_TUNABLES": NO_AVX},
}

CHILD = r"""
import hashlib, json, sys
from dataclasses import replace
import numpy as np
sys.path.insert(0, sys.argv[1])
import make_golden
names = json.loads(sys.argv[2])
# the cases asked for only (no scene cases: they load the scene files) and their schedules
cases = {c.name: c for c in make_golden.effect_cases() + make_golden.hard_cases()}
with np.load(make_golden.GOLDEN) as f:
    steps = {name: f[name + "/steps"] for name in names}
out = {}
for name in names:
    got = make_golden.run_case(replace(cases[name], steps=steps[name]))
    h = hashlib.sha256()
    for k in sorted(got):
        h.update(k.encode() + np.ascontiguousarray(got[k], dtype=float).tobytes())
    out[name] = h.hexdigest()
if sys.argv[3]:
    import fmpy
    start = json.loads(sys.argv[4])
    res = fmpy.simulate_fmu(sys.argv[3], stop_time=float(sys.argv[5]), output_interval=1e-4,
                            start_values=start, output=["dte", "mesh_force", "contact_state"])
    out["fmu via fmpy"] = hashlib.sha256(np.ascontiguousarray(
        np.column_stack([res[k] for k in res.dtype.names]), dtype=float).tobytes()).hexdigest()
print("DIGESTS " + json.dumps(out))
"""


def golden_digest(gold: dict, name: str) -> str:
    h = hashlib.sha256()
    keys = sorted(k.rsplit("/", 1)[1] for k in gold if k.rsplit("/", 1)[0] == name)
    for k in keys:
        h.update(k.encode() + np.ascontiguousarray(gold[f"{name}/{k}"], dtype=float).tobytes())
    return h.hexdigest()


def cpu_flags() -> set[str]:
    with open("/proc/cpuinfo") as fh:
        return set(next((ln.split(":", 1)[1].split() for ln in fh if ln.startswith("flags")),
                        []))


def child_env(extra: dict) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_CORETYPE", "GLIBC_TUNABLES", "OPENBLAS_NUM_THREADS")}
    return env | extra


def resonance_start(fmu_path) -> dict:
    from gearpair.bench.chost import fmu_start

    case = {c.name: c for c in make_golden.hard_cases()}[RESONANCE]
    start = fmu_start(fmu_path, "stick_slip", 1e-8, effects=case.effects)
    start.update(torque=float(case.steps[0, 1]), speed=float(case.steps[0, 2]))
    return start


@pytest.fixture(scope="module")
def runs(fmu_path, tmp_path_factory):
    """Per environment: the digests of the golden cases, of the FMU through fmpy and of the
    FMU in the C host; plus the same in this process's environment."""
    from gearpair.bench import chost

    workdir = tmp_path_factory.mktemp("same_bits")
    host, why = chost.build_host(workdir)
    unit = chost.extract(fmu_path, workdir / "fmu") if host else None
    start = resonance_start(fmu_path)
    envs = {"this process's": {}} | ENVIRONMENTS
    if "avx512f" not in cpu_flags():  # OpenBLAS's AVX-512 kernel stops with SIGILL here
        envs.pop("OpenBLAS SkylakeX")
    out = {}
    for name, extra in envs.items():
        env = child_env(extra)
        proc = subprocess.run(
            [sys.executable, "-c", CHILD, str(HERE / "golden"), json.dumps(CASES),
             str(fmu_path), json.dumps(start), repr(FMU_STEPS * 1e-4)],
            capture_output=True, text=True, env=env, timeout=600)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("DIGESTS ")]
        assert proc.returncode == 0 and lines, f"{name}: {proc.stderr[-2000:]}"
        got = json.loads(lines[-1][len("DIGESTS "):])
        if host is not None:
            res = chost.run_host(host, unit, start, 1e-4, FMU_STEPS, 1, env=env)
            got["fmu in the C host"] = res["instances"][0]["digest"]
        out[name] = got
    return out, why


def test_golden_cases_are_the_same_bits_in_every_environment(runs):
    got, _ = runs
    with np.load(make_golden.GOLDEN) as f:
        gold = {k: f[k] for k in f.files}
    for case in CASES:
        want = golden_digest(gold, case)
        differ = [env for env, d in got.items() if d[case] != want]
        assert not differ, f"{case} differs from the golden file under: {differ}"


@pytest.mark.parametrize("how", ["fmu via fmpy", "fmu in the C host"])
def test_fmu_gives_the_same_bits_in_every_environment(runs, how):
    got, why = runs
    if how == "fmu in the C host" and why:
        pytest.skip(why)
    digests = {env: d[how] for env, d in got.items()}
    assert len(set(digests.values())) == 1, digests


def test_the_fmu_runs_the_golden_trajectory(fmu_path):
    """The FMU (engine compiled for x86-64-v2) reproduces the golden resonance case (Python
    API, engine compiled for this CPU) at every communication step, bit for bit."""
    import fmpy

    start = resonance_start(fmu_path)
    res = fmpy.simulate_fmu(str(fmu_path), stop_time=FMU_STEPS * 1e-4, output_interval=1e-4,
                            start_values=start, output=["dte", "mesh_force"])
    with np.load(make_golden.GOLDEN) as f:
        rows = f[f"{RESONANCE}/rows"]
    for k in ("dte", "mesh_force"):
        col = make_golden.OUT_FIELDS.index(k)
        assert np.array_equal(res[k][1:], rows[:FMU_STEPS, col]), k
