"""The driveline example (examples/driveline): Motor - GearPair - Load, described once in an
SSP file and run in fmpy's SSP simulator, libcosimpy and ecospy.

The system is the example's quick variant (`driveline_system.QUICK`: a light load and a stiff
droop, settled within 0.15 s, load step at 0.2 s), 0.35 s in 1e-4 s steps.

Tolerance of the agreement. Every master is a fixed-step Jacobi master, so with the same step
they compute the same thing: measured, ecos equals fmpy bit for bit, and libcosim (whose
time grid is integer nanoseconds, not ``t += h``) differs by at most 4e-11 of the DTE scale
and 1e-12 of the torques. What a different scheme or step would change is measured by the
step-size study of this run: 1e-4 s against 5e-5 s steps moves motor speed and torques by
1.6e-3 of their scale (rms; 9e-3 max) and the instantaneous DTE by 4e-2 (rms; 0.2 max). The
masters must agree 100 times better than that: 1e-5 of the scale for speeds and torques,
5e-4 for the vibration signals (DTE, mesh force, gear speed). Longer runs drift further
apart on libcosim's grid (3 s: 1e-4 of the DTE scale after the stick events; see
docs/driveline.md).

Masters that cannot be imported here (libcosimpy and ecospy ship x86_64 wheels only; ecospy
also needs the Debian package libtbb12) are skipped with the reason.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "examples" / "driveline"))

import driveline_system as ds  # noqa: E402

pytestmark = pytest.mark.fmu

H = 1e-4  # s, communication step of every master
STOP = ds.QUICK_STOP_TIME  # s
# largest master-to-master difference, relative to the signal's scale (see above)
AGREE = {"GearPair.dte": 5e-4, "GearPair.mesh_force": 5e-4, "GearPair.gear1_speed": 5e-4}
AGREE_DEFAULT = 1e-5
MASTERS = ("fmpy", "libcosim", "ecospy")
STEADY = (0.15, 0.2)  # s: window before the load step (settled: time constant 14 ms)
AFTER = (0.3, 0.35)  # s: window after it


@pytest.fixture(scope="module")
def ssp(fmu_path, tmp_path_factory) -> Path:
    """Motor.fmu and Load.fmu built fresh, the session's GearPair.fmu, the quick SSP."""
    out = tmp_path_factory.mktemp("driveline")
    return ds.sibling("build").build(out, overrides=ds.QUICK, gearpair_fmu=fmu_path,
                                     stop_time=STOP, step=H)


@pytest.fixture(scope="module")
def params(ssp) -> dict[str, dict]:
    return ds.read_parameters(ssp)


@pytest.fixture(scope="module")
def runs(ssp) -> dict[str, dict | str]:
    """``{master: results}``, or ``{master: reason}`` for a master that cannot run here."""
    compare = ds.sibling("compare")
    compare.share_gearpair()
    out: dict[str, dict | str] = {}
    for m in MASTERS:
        reason = compare.unavailable(m)
        out[m] = reason if reason else ds.sibling(f"run_{m}").run(ssp, STOP, H)
    return out


def result(runs, master: str) -> dict[str, np.ndarray]:
    r = runs[master]
    if isinstance(r, str):
        pytest.skip(f"{master}: {r}")
    return r


def window(res: dict[str, np.ndarray], signal: str, span: tuple[float, float]) -> float:
    t = res["time"]
    sel = (t > span[0] + 1e-9) & (t <= span[1] + 1e-9)
    return float(np.mean(res[signal][sel]))


# -- the pieces ---------------------------------------------------------------------------------
def test_component_fmus_validate(ssp):
    from fmpy.validation import validate_fmu

    for name in ("Motor.fmu", "Load.fmu"):
        assert validate_fmu(str(ssp.parent / name)) == [], name


def test_ssd_is_valid_and_carries_the_parameters(ssp, params):
    from fmpy.ssp.ssd import read_ssd

    ssd = read_ssd(str(ssp), validate=True)  # against the SSP 1.0 schema
    assert [c.name for c in ssd.system.elements] == list(ds.CONNECTORS)
    assert len(ssd.system.connections) == len(ds.CONNECTIONS)
    assert params == ds.merged_parameters(ds.QUICK)
    assert params["GearPair"]["load_speed_input"] is True
    assert params["GearPair"]["kr1"] > 0 and params["GearPair"]["torque"] == 0.0


def test_motor_step_is_exact_across_the_knees():
    """`motor.advance` against a tight numerical solution, through both torque limits."""
    from scipy.integrate import solve_ivp

    motor = ds.sibling("motor")
    J, T_stall, w0, T_max = 2.0, 12000.0, 50.0, 8000.0
    rhs = lambda _t, w: [(motor.characteristic(w[0], T_stall, w0, T_max) - load) / J]  # noqa: E731
    # up through w_lo, down through w_hi, inside the droop, and stalled on a limit
    for w, load, h in ((0.0, 3000.0, 0.05), (80.0, -2000.0, 0.05), (40.0, 500.0, 1e-3),
                       (-5.0, 9000.0, 0.01), (10.0, 8000.0, 0.02)):
        exact = motor.advance(w, load, h, J, T_stall, w0, T_max)
        ref = solve_ivp(rhs, (0.0, h), [w], rtol=1e-12, atol=1e-12, max_step=h / 200).y[0, -1]
        assert exact == pytest.approx(ref, rel=1e-8, abs=1e-9), (w, load, h)


def test_load_step_inside_a_communication_step():
    """A load change inside a step gives the same state as a step split at the change."""
    load = ds.sibling("load")

    def run(points):
        s = load.Load(instance_name="load", resources=".")
        s.T_step, s.t_step, s.torque = 4000.0, 0.013, 9000.0
        s.exit_initialization_mode()
        for t0, t1 in zip(points[:-1], points[1:], strict=True):
            assert s.do_step(t0, t1 - t0)
        return s.speed

    assert run([0.0, 0.02]) == pytest.approx(run([0.0, 0.013, 0.02]), rel=1e-13)
    assert run([0.0, 0.005, 0.02]) == pytest.approx(run([0.0, 0.013, 0.016, 0.02]), rel=1e-13)


# -- the system in each master --------------------------------------------------------------------
@pytest.mark.parametrize("master", ("libcosim", "ecospy"))
def test_masters_agree(runs, master):
    """Motor speed, output torque and DTE (and every other recorded signal) agree with fmpy's
    SSP simulator after every step; the contact states are identical."""
    ref, res = result(runs, "fmpy"), result(runs, master)
    assert len(res["time"]) == len(ref["time"]) == round(STOP / H)
    np.testing.assert_allclose(res["time"], ref["time"], rtol=0, atol=1e-12)
    for sig in ds.SIGNALS:
        scale = float(np.max(np.abs(ref[sig])))
        err = float(np.max(np.abs(res[sig] - ref[sig])))
        assert err <= AGREE.get(sig, AGREE_DEFAULT) * scale, (master, sig, err / scale)
    np.testing.assert_array_equal(res["GearPair.contact_state"], ref["GearPair.contact_state"])


@pytest.mark.parametrize("master", MASTERS)
def test_steady_speed_matches_the_characteristic(runs, params, master):
    """Settled, the motor turns where its characteristic meets the load torque reflected
    through z1/z2, and the load turns z1/z2 times slower."""
    res = result(runs, master)
    r = ds.mesh_ratio(params)
    m = params["Motor"]
    w = window(res, "Motor.speed", STEADY)
    w_load = window(res, "Load.speed", STEADY)
    t_in = window(res, "GearPair.input_torque", STEADY)
    predicted = ds.steady_state(params)
    # mesh losses (friction) and the residual ripple stay below 0.1 % here
    assert w == pytest.approx(predicted["motor_speed"], rel=3e-3)
    assert w_load == pytest.approx(r * w, rel=1e-3)
    # the characteristic at the torque the gear pair actually draws
    assert w == pytest.approx(m["w_noload"] * (1.0 - t_in / m["T_stall"]), rel=3e-3)
    assert t_in == pytest.approx(predicted["motor_torque"], rel=2e-2)
    assert window(res, "GearPair.output_torque", STEADY) == pytest.approx(
        window(res, "Load.resisting_torque", STEADY), rel=1e-2)


@pytest.mark.parametrize("master", MASTERS)
def test_power_flows_both_ways(runs, params, master):
    """A load torque step on the output shaft reaches the motor: it slows down by what the
    characteristic says and supplies the reflected extra torque."""
    res = result(runs, master)
    r = ds.mesh_ratio(params)
    step = params["Load"]["T_step"]
    before, after = ds.steady_state(params), ds.steady_state(params, step)
    drop = window(res, "Motor.speed", STEADY) - window(res, "Motor.speed", AFTER)
    rise = window(res, "GearPair.input_torque", AFTER) - window(res, "GearPair.input_torque",
                                                              STEADY)
    assert drop > 0.0
    assert drop == pytest.approx(before["motor_speed"] - after["motor_speed"], rel=3e-2)
    assert rise == pytest.approx(after["motor_torque"] - before["motor_torque"], rel=5e-2)
    assert rise == pytest.approx(r * step, rel=5e-2)
    assert window(res, "Motor.speed", AFTER) == pytest.approx(after["motor_speed"], rel=3e-3)
