"""GearPair.fmu follows the FMI 2.0 co-simulation state machine and refuses invalid settings
as the standard says, through fmpy's low-level FMU2Slave.

Every refusal is checked for its status (fmi2Error), its log message (in the FMU's names,
units and integer codes, delivered also with loggingOn = false), and for having changed
nothing: the value or state is kept and the next legal step gives bit for bit what an
instance that never saw the refused call gives.
"""

from __future__ import annotations

import math

import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

from fmpy import extract  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import fmi2Error, fmi2OK  # noqa: E402
from fmu_slave import LoggingSlave  # noqa: E402

pytestmark = pytest.mark.fmu

RTOL = 1e-6
OUTPUTS = ("dte", "mesh_force", "friction_force", "output_torque", "gear1_speed",
           "gear2_speed", "stick_fraction", "mesh_force_max")


@pytest.fixture(scope="module")
def unzipdir(fmu_path, tmp_path_factory) -> str:
    return str(extract(str(fmu_path), unzipdir=str(tmp_path_factory.mktemp("sm_unzip"))))


class G(LoggingSlave):
    def init(self, **start) -> None:
        self.fmu.setupExperiment(startTime=0.0)
        self.set(rtol=RTOL, **start)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def outputs(self) -> tuple:
        return tuple(self.fmu.getReal([self.vr[n] for n in OUTPUTS])) + tuple(
            self.fmu.getInteger([self.vr["contact_state"], self.vr["n_events"]]))

    def steps(self, t: float, n: int, h: float = 1e-4) -> tuple[float, list[tuple]]:
        rows = []
        for _ in range(n):
            self.fmu.doStep(t, h)  # raises unless fmi2OK or fmi2Warning
            t += h
            rows.append(self.outputs())
        return t, rows

    def refused(self, call, *args, **kwargs) -> str:
        """Run a call that must be refused with fmi2Error; return its error message."""
        n = len(self.messages)
        with pytest.raises(FMICallException) as exc:
            call(*args, **kwargs)
        assert exc.value.status == fmi2Error
        errors = [m for s, m in self.messages[n:] if s == fmi2Error]
        assert errors, "no error message logged"
        return errors[-1]


def reference(md, unzipdir, n: int, **start) -> list[tuple]:
    g = G(md, unzipdir, "ref")
    g.init(**start)
    _, rows = g.steps(0.0, n)
    g.fmu.terminate()
    g.fmu.freeInstance()
    return rows


def test_do_step_before_exit_initialization_mode_is_an_error(md, unzipdir):
    g = G(md, unzipdir)
    msg = g.refused(g.fmu.doStep, 0.0, 1e-4)  # instantiated
    assert "fmi2DoStep" in msg and "instantiated" in msg
    g.fmu.setupExperiment(startTime=0.0)
    g.set(rtol=RTOL)
    g.fmu.enterInitializationMode()
    msg = g.refused(g.fmu.doStep, 0.0, 1e-4)
    assert "initialization mode" in msg and "fmi2ExitInitializationMode" in msg
    g.fmu.exitInitializationMode()
    _, rows = g.steps(0.0, 2)
    assert rows == reference(md, unzipdir, 2)
    g.fmu.terminate()
    g.fmu.freeInstance()


@pytest.mark.parametrize("name, value, start", [
    ("kb2", 0.0, 4.11e10), ("load_speed_input", True, False), ("friction_law", 0, 3),
    ("mu", 0.05, 0.02)])
def test_fixed_parameter_after_initialization_is_refused_and_kept(md, unzipdir, name, value,
                                                                  start):
    g = G(md, unzipdir)
    g.init()
    t, rows = g.steps(0.0, 2)
    msg = g.refused(g.set, **{name: value})
    assert name in msg and "fixed" in msg
    assert g.outputs() == rows[-1]
    kept = {bool: g.fmu.getBoolean, int: g.fmu.getInteger, float: g.fmu.getReal}[type(value)]
    assert float(kept([g.vr[name]])[0]) == float(start)
    _, more = g.steps(t, 2)
    assert rows + more == reference(md, unzipdir, 4)
    g.fmu.terminate()
    g.fmu.freeInstance()


@pytest.mark.parametrize("name, value, words", [
    ("mu", -1.0, ("mu = -1", "allowed [0, 1]")),
    ("mu", math.inf, ("mu = inf", "not finite")),
    ("m1", 0.0, ("m1 = 0 kg", "(0, 100000] kg")),
    ("speed", math.nan, ("speed", "not finite", "rad/s")),
    ("torque", 2e6, ("torque = 2000000 N.m", "[-1000000, 1000000] N.m")),
    ("friction_law", 7, ("friction_law = 7", "0 (off), 1 (nominal), 2 (regularized), "
                                             "3 (stick_slip)")),
    ("dof", -1, ("dof = -1", "0 (full), 1 (torsional)")),
])
def test_invalid_value_is_refused_when_set_and_the_old_value_kept(md, unzipdir, name, value,
                                                                  words):
    g = G(md, unzipdir)
    g.fmu.setupExperiment(startTime=0.0)
    msg = g.refused(g.set, **{name: value})
    assert all(w in msg for w in words), msg
    g.set(rtol=RTOL)
    g.fmu.enterInitializationMode()
    var = next(v for v in md.modelVariables if v.name == name)
    start = int(var.start) if var.type == "Integer" else float(var.start)
    get = g.fmu.getInteger if var.type == "Integer" else g.fmu.getReal
    assert get([var.valueReference]) == [start]  # the old value kept
    # remembered: initialization ends only once a valid value is set again
    assert f"{name} = " in g.refused(g.fmu.exitInitializationMode)
    g.set(**{name: start})
    if name in ("speed", "torque"):  # inputs: refused in step mode as well
        g.fmu.exitInitializationMode()
        t, rows = g.steps(0.0, 1)
        msg = g.refused(g.set, **{name: value})
        assert all(w in msg for w in words), msg
        assert g.outputs() == rows[-1]
        _, more = g.steps(t, 1)
        assert rows + more == reference(md, unzipdir, 2)
    else:
        g.fmu.exitInitializationMode()
        _, rows = g.steps(0.0, 2)
        assert rows == reference(md, unzipdir, 2)
    g.fmu.terminate()
    g.fmu.freeInstance()


def test_invalid_combination_is_refused_at_exit_initialization_mode(md, unzipdir):
    """dof = 1 with friction_law = 3 and sliding = 0: fmi2Error at
    fmi2ExitInitializationMode with the combination in the FMU's codes; the instance stays
    in initialization mode, so a corrected setting and a new fmi2ExitInitializationMode
    work, and so does fmi2Reset."""
    g = G(md, unzipdir)
    g.fmu.setupExperiment(startTime=0.0)
    g.set(rtol=RTOL, dof=1)
    g.fmu.enterInitializationMode()
    msg = g.refused(g.fmu.exitInitializationMode)
    assert "dof = 1 (torsional) with friction_law = 3 (stick_slip) needs sliding = 1 (full)" \
        in msg
    g.refused(g.fmu.doStep, 0.0, 1e-4)  # still in initialization mode
    g.set(sliding=1)
    g.fmu.exitInitializationMode()
    _, rows = g.steps(0.0, 2)
    assert rows == reference(md, unzipdir, 2, dof=1, sliding=1)

    g.fmu.reset()  # back to instantiated with the start values
    g.fmu.setupExperiment(startTime=0.0)
    g.set(rtol=RTOL, dof=1)
    g.fmu.enterInitializationMode()
    g.refused(g.fmu.exitInitializationMode)
    g.fmu.reset()
    g.init()
    _, rows = g.steps(0.0, 2)
    assert rows == reference(md, unzipdir, 2)
    g.fmu.terminate()
    g.fmu.freeInstance()


def test_errors_reach_the_logger_with_logging_off_and_debug_messages_do_not(md, unzipdir):
    quiet = G(md, unzipdir, "quiet", logging_on=False)
    quiet.fmu.setupExperiment(tolerance=1e-4, startTime=0.0)  # logs an OK-status note
    assert not any(s == fmi2OK for s, _ in quiet.messages), quiet.messages
    n = len(quiet.messages)
    msg = quiet.refused(quiet.set, mu=-1.0)
    assert "mu = -1" in msg
    assert [s for s, _ in quiet.messages[n:]] == [fmi2Error]
    quiet.fmu.freeInstance()

    loud = G(md, unzipdir, "loud")
    loud.fmu.setupExperiment(tolerance=1e-4, startTime=0.0)
    assert any(s == fmi2OK and "tolerance" in m for s, m in loud.messages)
    loud.fmu.setDebugLogging(False, [])  # debug off again: errors still come through
    n = len(loud.messages)
    loud.refused(loud.set, mu=-1.0)
    assert [s for s, _ in loud.messages[n:]] == [fmi2Error]
    loud.fmu.freeInstance()


def test_calls_out_of_order_are_refused(md, unzipdir):
    g = G(md, unzipdir)
    assert "not allowed in instantiated" in g.refused(g.fmu.getReal, [g.vr["dte"]])
    assert "fmi2Terminate" in g.refused(g.fmu.terminate)
    assert "fmi2ExitInitializationMode" in g.refused(g.fmu.exitInitializationMode)
    g.init()
    assert "fmi2SetupExperiment" in g.refused(g.fmu.setupExperiment, None, 0.0)
    assert "fmi2EnterInitializationMode" in g.refused(g.fmu.enterInitializationMode)
    assert "output" in g.refused(g.fmu.setReal, [g.vr["dte"]], [0.0])
    assert "value reference 9999" in g.refused(g.fmu.getReal, [9999])
    t, rows = g.steps(0.0, 1)
    g.fmu.terminate()
    assert "terminated" in g.refused(g.fmu.doStep, t, 1e-4)
    assert "terminated" in g.refused(g.set, torque=1000.0)
    assert g.outputs() == rows[-1]  # outputs can still be read after terminate
    g.fmu.freeInstance()


def test_truncated_or_altered_serialized_state_is_refused(md, unzipdir):
    g = G(md, unzipdir)
    g.init()
    t, rows = g.steps(0.0, 2)
    s = g.fmu.getFMUstate()
    blob = bytes(g.fmu.serializeFMUstate(s))
    g.fmu.freeFMUstate(s)
    flipped = bytearray(blob)
    flipped[len(blob) // 2] ^= 0x10
    for bad in (blob[: len(blob) // 2], blob[:-1], bytes(flipped), b""):
        msg = g.refused(g.fmu.deSerializeFMUstate, bad)
        assert "checksum" in msg
        assert g.outputs() == rows[-1]
    s = g.fmu.deSerializeFMUstate(blob)  # the intact one restores
    _, more = g.steps(t, 2)
    g.fmu.setFMUstate(s)
    g.fmu.freeFMUstate(s)
    _, again = g.steps(t, 2)
    assert again == more and rows + more == reference(md, unzipdir, 4)
    g.fmu.terminate()
    g.fmu.freeInstance()


def test_a_value_refused_before_initialization_stops_exit_initialization_mode(md, unzipdir):
    """Masters that ignore fmi2SetReal's status (OMSimulator) must not run with a value the
    user did not get: a refused start value makes fmi2ExitInitializationMode return
    fmi2Error naming it, until a valid value for it is set; then the run is that of an
    instance given the valid value at once."""
    g = G(md, unzipdir)
    g.fmu.setupExperiment(startTime=0.0)
    g.refused(g.set, mu=-1.0)  # instantiated
    g.set(rtol=RTOL)
    g.fmu.enterInitializationMode()
    msg = g.refused(g.fmu.exitInitializationMode)
    assert "mu = -1 was refused at fmi2SetReal; set a valid value or leave it unset" in msg
    msg = g.refused(g.fmu.exitInitializationMode)  # still in initialization mode, still so
    assert "mu = -1 was refused" in msg
    g.set(mu=0.05)
    g.fmu.exitInitializationMode()
    assert g.fmu.getReal([g.vr["mu"]]) == [0.05]
    _, rows = g.steps(0.0, 3)
    assert rows == reference(md, unzipdir, 3, mu=0.05)


def test_every_value_of_a_refused_call_is_named_and_reset_forgets_them(md, unzipdir):
    """One fmi2SetReal with a valid and an invalid value takes neither: both are named (in
    initialization mode as before it); an Integer code too. fmi2Reset starts afresh."""
    g = G(md, unzipdir)
    g.fmu.setupExperiment(startTime=0.0)
    g.fmu.enterInitializationMode()
    g.refused(g.fmu.setReal, [g.vr["m1"], g.vr["rtol"]], [2.0, 0.5])
    g.refused(g.set, friction_law=7)
    msg = g.refused(g.fmu.exitInitializationMode)
    assert "m1 = 2 was not taken" in msg and "rtol = 0.5 was refused at fmi2SetReal" in msg
    assert "friction_law = 7 was refused at fmi2SetInteger" in msg
    assert "set valid values or leave them unset" in msg
    g.set(m1=2.0, rtol=RTOL)
    assert "friction_law = 7" in g.refused(g.fmu.exitInitializationMode)
    g.fmu.reset()
    g.init()
    g.steps(0.0, 1)
    g.fmu.terminate()
    g.fmu.freeInstance()


def test_an_unbounded_response_ends_the_step_with_fmi2error_and_says_why(md, unzipdir):
    """Issue 38: at 7250 r/min, 10 kN.m and 10 um of backlash the impacts grow without
    bound (the engines stop near t = 0.026 s). The step where the DTE leaves its bound
    returns fmi2Error with the engine's message, logged with logging off too; the steps
    before it are fmi2OK."""
    g = G(md, unzipdir, "unbounded")
    g.init(backlash=1e-5, torque=10000.0, speed=7250.0 * 2.0 * math.pi / 60.0)
    t, ok = 0.0, 0
    n = len(g.messages)
    with pytest.raises(FMICallException) as exc:
        for _ in range(600):
            g.fmu.doStep(t, 1e-4)
            t += 1e-4
            ok += 1
    assert exc.value.status == fmi2Error
    assert 0.02 < t < 0.04 and ok > 150
    errors = [m for s, m in g.messages[n:] if s == fmi2Error]
    assert errors and "unbounded response" in errors[-1] and "DTE" in errors[-1]
    g.fmu.freeInstance()
