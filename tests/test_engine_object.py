"""The fast engine as an object file (`gearpair.aot`): a C program linked with it runs the
model with no Python and no numba, and gives the Python API's bits.

The program goes through the C model part (`fmu_src/c/gearpair_model.c`) as an FMU's C layer
will, restores a state it copied halfway, which must repeat the second half, and runs two
more instances in two threads at once, which must repeat the serial run. The object
is numba's own code for the portable CPU, so the comparison is bit for bit, for several
scenes: stick-slip, own gear geometry, each stiffness law, backlash with the exact
propagator, the torsional model with Dormand-Prince 5(4). The program runs with an empty
environment and `ldd` shows it needs only the C library.
"""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gearpair import Effects, GearParams
from gearpair.engine import StepSummary
from gearpair.fast import setup as S
from gearpair.fast.engine import FastEngine, FastOptions
from gearpair.stepblock import STEP_RECORD, X_REC

ROOT = Path(__file__).resolve().parents[1]
RPM = 2 * math.pi / 60

pytestmark = [pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler"),
              pytest.mark.filterwarnings("ignore::gearpair.geometry.GearDataWarning")]

CASES = {
    "stick_slip": (GearParams(), Effects(), {}, 3953.8, 100 * RPM),
    "own_geometry": (GearParams(module=4e-3, z1=25, z2=60, face_width=0.1), Effects(), {},
                     1500.0, 300 * RPM),
    "constant_regularized": (GearParams(), Effects(stiffness="constant",
                                                   friction="regularized"), {}, 3000.0,
                             500 * RPM),
    "rectangular_backlash_exact": (GearParams(), Effects(friction="off", stiffness="rectangular",
                                                         backlash=5e-5), {}, 1000.0,
                                   5000 * RPM),
    "torsional_dp5": (GearParams(), Effects(dof="torsional", sliding="full"),
                      {"method": "dp5"}, 2000.0, 200 * RPM),
}


@pytest.fixture(scope="module")
def engine_run(tmp_path_factory):
    """The C program `fmu_src/c/engine_run.c` linked with the engine's object."""
    from gearpair import aot

    where = tmp_path_factory.mktemp("engine")
    made = aot.write_engine(where)
    assert aot.undefined_symbols(made["object"]) == sorted(aot.LIBC)
    exe = where / "engine_run"
    c = ROOT / "fmu_src" / "c"
    subprocess.run(["cc", "-O2", "-pthread", "-Wall", "-Wextra", "-Werror", "-o", str(exe),
                    str(c / "engine_run.c"), str(c / "gearpair_model.c"), made["object"],
                    f"-I{where}", f"-I{c}", "-lm"], check=True)
    return exe


def _python_records(p, fx, opts, rtol, run):
    t0, dt, steps, torque, speed = run
    e = FastEngine(p, fx, rtol=rtol, **opts)
    e.reset(t0, torque, speed)
    o = e.outputs()
    rows = [np.array([o.dte, o.mesh_force, o.friction_force, o.contact_state,
                      o.output_torque, o.input_torque_reaction, o.input_torque,
                      o.gear1_speed, o.gear2_speed, o.sliding_velocity]
                     + list(StepSummary.at_instant(o))[2:], dtype=float)]
    for _ in range(steps):  # as a master steps an FMU: from its time t to t + dt
        e.advance_values(e.time + dt, torque, speed)
        rows.append(e.block[X_REC:X_REC + len(STEP_RECORD)].copy())
    return np.array(rows)


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_c_program_gives_the_python_bits(engine_run, case):
    p, fx, opts, torque, speed = CASES[case]
    rtol, run = 1e-8, (0.0, 1e-4, 60, torque, speed)
    text = " ".join(repr(float(v)) for v in S.gear_vector(p)) + "\n" + \
        " ".join(repr(float(v)) for v in S.choice_vector(
            p, fx, rtol=rtol, options=FastOptions(**opts))) + "\n" + \
        " ".join(repr(v) for v in (run[0], run[1], run[2], torque, speed)) + "\n"
    proc = subprocess.run([str(engine_run), "--threads"], input=text, capture_output=True,
                          text=True, env={}, timeout=120)
    assert proc.returncode == 0, proc.stderr  # (also two instances in two threads at once)
    got = np.array([[float.fromhex(w) for w in line.split()]
                    for line in proc.stdout.splitlines()])
    want = _python_records(p, fx, opts, rtol, run)
    assert got.shape == want.shape
    assert np.array_equal(got, want), np.argwhere(got != want)[:5]
    assert np.ptp(got[:, 0]) > 0  # the gears vibrate


def test_the_c_program_needs_only_the_c_library(engine_run):
    libs = subprocess.run(["ldd", str(engine_run)], capture_output=True, text=True).stdout
    assert "python" not in libs.lower() and "numba" not in libs.lower()


def test_refused_gear_data_are_named(engine_run):
    p = GearParams(addendum_coef=0.5)  # contact ratio below 1
    text = " ".join(repr(float(v)) for v in S.gear_vector(p)) + "\n" + \
        " ".join(repr(float(v)) for v in S.choice_vector(p)) + "\n0 1e-4 2 100 10\n"
    proc = subprocess.run([str(engine_run)], input=text, capture_output=True, text=True,
                          env={}, timeout=60)
    assert proc.returncode == 2 and "contact ratio below 1" in proc.stderr
