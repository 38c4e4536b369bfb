"""Seeded fuzz test of GearPair3.fmu's FMI 3.0 state machine through a C host.

``tests/fuzz/fmi3_fuzz.c`` (built here with gcc against fmpy's FMI 3 headers) loads the FMU
like any C master and runs random legal and illegal call sequences until it has made
N_CALLS fmi3 calls per seed: its own model of the FMI 3.0 co-simulation state machine
(Event Mode and early return allowed or not, per instance) says which calls are legal, and
it requires no fmi3Fatal, legal calls to succeed and illegal ones to return fmi3Error,
refused calls to leave the outputs as they were, the flags of fmi3DoStep to agree with the
instance's (an early return only when allowed, inside the step; eventHandlingNeeded only
with Event Mode), the variable time to read the driver's time, and replays from saved,
deserialized and freshly restored states to be bit-identical, early returns included. The
inputs' normal bands put the gears at 3000 to 6000 r/min under a light torque, where
contact is lost and regained every few tenths of a millisecond: the steps return early.
It runs in a child process with an empty environment (no Python).

Seeds are fixed, so a failure reproduces: rerun the printed command line.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")

from test_hosts import _signal_name, compile_c_host  # noqa: E402

pytestmark = pytest.mark.fmu

FUZZ_C = Path(__file__).resolve().parent / "fuzz" / "fmi3_fuzz.c"
SEEDS = (1, 2, 3)
N_CALLS = 100_000  # fmi3 calls per seed (about 1 s)
TIME_LIMIT = 60.0  # s, per seed
# Bands the fuzzer draws "normal" values from (others stay at their start value); every
# variable still gets out-of-range, NaN and infinite values, and inputs their range ends.
SAFE = {
    "torque": (100.0, 1000.0), "speed": (300.0, 600.0), "load_speed": (0.0, 20.0),
    "mu": (0.0, 0.1), "damping_ratio": (0.01, 0.1), "rtol": (1e-9, 1e-6),
    "stiffness_model": (0, 2), "friction_law": (0, 3), "sliding": (0, 1), "stick_tie": (0, 1),
    "dof": (0, 1), "engine": (0, 0),
}
KINDS = {"Float64": "F", "Int32": "I", "Enumeration": "E", "Boolean": "B"}
CAUSALITY = {"input": "i", "parameter": "p", "output": "o", "independent": "t"}


def fuzz_spec(md3) -> str:
    """The fuzzer's variable list: KIND VR LO HI SAFE_LO SAFE_HI NAME per line."""
    lines = []
    for v in md3.modelVariables:
        lo = float(v.min) if v.min is not None else -1e300
        hi = float(v.max) if v.max is not None else 1e300
        start = float(v.start) if v.start not in (None, "true", "false") else 0.0
        safe = SAFE.get(v.name, (start, start))
        lines.append(f"{KINDS[v.type]}{CAUSALITY[v.causality]} {v.valueReference} {lo!r} "
                     f"{hi!r} {float(safe[0])!r} {float(safe[1])!r} {v.name}")
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def fuzzer(tmp_path_factory) -> Path:
    return compile_c_host(FUZZ_C, tmp_path_factory.mktemp("fuzz3") / "fmi3_fuzz")


@pytest.fixture(scope="module")
def case(fmu3_path, tmp_path_factory) -> dict:
    md3 = fmpy.read_model_description(str(fmu3_path))
    base = tmp_path_factory.mktemp("fuzz3_fmu")
    unzip = Path(fmpy.extract(str(fmu3_path), unzipdir=str(base / "unzip")))
    spec = base / "spec.txt"
    spec.write_text(fuzz_spec(md3))
    return {"unzip": unzip, "spec": spec, "md3": md3}


@pytest.mark.parametrize("seed", SEEDS)
def test_fmi3_call_sequence_fuzz(case, fuzzer, seed):
    md3 = case["md3"]
    cmd = [str(fuzzer), str(case["unzip"]), md3.coSimulation.modelIdentifier, md3.guid,
           str(case["spec"]), str(seed), str(N_CALLS)]
    try:
        proc = subprocess.run(cmd, env={"PATH": "/usr/bin:/bin"}, capture_output=True,
                              text=True, timeout=TIME_LIMIT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the fuzzer hung (over {TIME_LIMIT} s): {' '.join(cmd)}")
    assert proc.returncode == 0, (f"rc {_signal_name(proc.returncode)}; rerun: "
                                  f"{' '.join(cmd)}\n{proc.stderr[-3000:]}")
    calls = int(proc.stdout.split()[1])
    assert calls >= N_CALLS, proc.stdout
    early = int(proc.stdout.split("early returns ")[1].split(",")[0])
    assert early > 0, proc.stdout  # the sequences do return early
