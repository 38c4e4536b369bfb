"""Seeded fuzz test of GearPair.fmu's FMI 2.0 interface through a C host.

``tests/fuzz/fmi2_fuzz.c`` (built here with gcc against fmpy's FMI 2 headers) loads the FMU
like any C master and runs random legal and illegal call sequences: inputs and parameters
set to normal, range-end, out-of-range, NaN and infinite values; steps of every size
including zero, negative, NaN and at a wrong communication point; FMU states got, set, freed,
serialized and deserialized, also truncated and bit-flipped; reset, free and re-instantiate;
calls out of order. It keeps its own model of the FMI state machine and requires: no
fmi2Fatal, legal calls succeed and illegal ones return fmi2Error, a refused call leaves the
outputs unchanged and finite and a legal step works after it, replay from a saved or
deserialized state (also in a fresh instance) is bit-identical. The fuzzer runs in a child
process (the non-Python host path, with an empty environment), which must
exit with status 0 within its time limit.

Seeds are fixed, so a failure reproduces: rerun the printed command line.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")

from test_hosts import _signal_name, compile_c_host, native_env  # noqa: E402

pytestmark = pytest.mark.fmu

FUZZ_C = Path(__file__).resolve().parent / "fuzz" / "fmi2_fuzz.c"
SEEDS = (1, 2, 3)
N_OPS = 400
TIME_LIMIT = 60.0  # s, per seed (the whole test stays well below it on a quiet machine)

# Bands the fuzzer draws "normal" values from (others stay at their start value, so that
# the engine's cost stays bounded); every variable still gets out-of-range, NaN and
# infinite values, and inputs their range ends.
SAFE = {
    "torque": (0.0, 5000.0), "speed": (5.0, 20.0), "load_speed": (0.0, 20.0),
    "mu": (0.0, 0.1), "damping_ratio": (0.01, 0.1), "rtol": (1e-9, 1e-6),
    "stiffness_model": (0, 2), "friction_law": (0, 3), "sliding": (0, 1), "stick_tie": (0, 1),
    "dof": (0, 1), "engine": (0, 0),
}


def fuzz_spec(md) -> str:
    """The fuzzer's variable list: KIND VR LO HI SAFE_LO SAFE_HI NAME per line."""
    lines = []
    for v in md.modelVariables:
        kind = v.type[0] + {"input": "i", "parameter": "p", "output": "o"}[v.causality]
        lo = float(v.min) if v.min is not None else -1e300
        hi = float(v.max) if v.max is not None else 1e300
        start = float(v.start) if v.start not in (None, "true", "false") else 0.0
        safe = SAFE.get(v.name, (start, start))
        lines.append(f"{kind} {v.valueReference} {lo!r} {hi!r} {float(safe[0])!r} "
                     f"{float(safe[1])!r} {v.name}")
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def fuzzer(tmp_path_factory) -> Path:
    return compile_c_host(FUZZ_C, tmp_path_factory.mktemp("fuzz") / "fmi2_fuzz")


@pytest.mark.parametrize("seed", SEEDS)
def test_fmi_call_sequence_fuzz(fmu_path, md, tmp_path, fuzzer, seed):
    env = native_env()
    unzipdir = Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "unzip")))
    spec = tmp_path / "spec.txt"
    spec.write_text(fuzz_spec(md))
    cmd = [str(fuzzer), str(unzipdir), md.coSimulation.modelIdentifier, md.guid, str(spec),
           str(seed), str(N_OPS)]
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True,
                              timeout=TIME_LIMIT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the fuzzer hung (over {TIME_LIMIT} s): {' '.join(cmd)}")
    assert proc.returncode == 0, (f"rc {_signal_name(proc.returncode)}; rerun: "
                                  f"{' '.join(cmd)}\n{proc.stderr[-3000:]}")
    summary = proc.stdout.split("\n")[0]
    assert summary.startswith(f"ops {N_OPS};") and "fatal 0" in summary, proc.stdout
    assert "error 0" not in summary  # the refusals were exercised and logged
