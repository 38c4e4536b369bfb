"""GearPair3.fmu, the FMI 3.0 co-simulation build (#35), in fmpy: its modelDescription is
GearPair.fmu's in FMI 3 (same variables, value references, units, ranges and start values;
the integer-coded choices as Enumerations; Event Mode and early return declared) and
validates clean; its binaries are for the same platforms, and the Linux one needs no Python;
without early return its outputs are GearPair.fmu's bit for bit, also with Event Mode and
early return allowed; the FMI 3 state machine refuses what it must, with a message that
reaches the logger with logging off; FMU states replay bit for bit, also serialized into a
fresh instance."""

from __future__ import annotations

import math
import re
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

import test_win64  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi3 import FMU3Slave, fmi3LogMessageCallback  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402
from test_win64 import compile_win64_host, winpath  # noqa: E402

wine = test_win64.wine  # its fixture: a Windows program run under Wine

pytestmark = pytest.mark.fmu

ROOT = Path(__file__).resolve().parents[1]
RPM = 2.0 * math.pi / 60.0
# scenes by start values (names of both FMUs) and their length (s): stick-slip (the default
# law with mu = 0.06), contact loss (a light torque at 5000 r/min), and backlash with back-flank
# impacts (friction off, 10 kN.m at 5000 r/min)
SCENES = {"stick_slip": ({"mu": 0.06, "rtol": 1e-6}, 0.02),
          "contact_loss": ({"torque": 300.0, "speed": 5000 * RPM, "rtol": 1e-6}, 0.005),
          "backlash": ({"friction_law": 0, "backlash": 1e-4, "torque": 10000.0,
                        "speed": 5000 * RPM, "rtol": 1e-6}, 0.005)}


@pytest.fixture(scope="module")
def md3(fmu3_path):
    return fmpy.read_model_description(str(fmu3_path))


@pytest.fixture(scope="module")
def unzip3(fmu3_path, tmp_path_factory) -> Path:
    return Path(fmpy.extract(str(fmu3_path), unzipdir=str(tmp_path_factory.mktemp("unzip3"))))


# -- the modelDescription ---------------------------------------------------------------------
def test_validate_finds_no_problems_and_the_flags_are_declared(fmu3_path, md3, md):
    assert validate_fmu(str(fmu3_path)) == []
    cs = md3.coSimulation
    assert md3.fmiVersion == "3.0" and cs.modelIdentifier == "GearPair3"
    assert cs.hasEventMode and cs.mightReturnEarlyFromDoStep
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate  # fmpy reads FMUState so
    assert cs.canHandleVariableCommunicationStepSize and not cs.needsExecutionTool
    assert md3.modelExchange is None and md3.scheduledExecution is None
    assert md3.guid == md.guid  # the instantiation token: the shared variable table's GUID
    de2, de3 = md.defaultExperiment, md3.defaultExperiment
    assert (de3.startTime, de3.stopTime, de3.stepSize) == (de2.startTime, de2.stopTime,
                                                          de2.stepSize)


def test_the_same_variables_value_references_units_and_ranges_in_fmi3_types(md, md3):
    import importlib.util

    spec = importlib.util.spec_from_file_location("_fmu_interface3",
                                                  ROOT / "fmu_src" / "fmu_interface.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    codes = {v["name"]: v["codes"] for v in mod.interface() if v["codes"]}
    v3 = {v.name: v for v in md3.modelVariables}
    time, = [v for v in md3.modelVariables if v.causality == "independent"]
    assert time.name == "time" and time.type == "Float64"
    assert time.valueReference == max(v.valueReference for v in md.modelVariables) + 1
    assert set(v3) == {v.name for v in md.modelVariables} | {"time"}
    for v in md.modelVariables:
        w = v3[v.name]
        want = {"Real": "Float64", "Boolean": "Boolean"}.get(v.type) or \
            ("Enumeration" if v.name in codes else "Int32")
        assert w.type == want, v.name
        for key in ("valueReference", "causality", "variability", "initial", "unit",
                    "displayUnit", "min", "max", "start", "description"):
            assert getattr(w, key) == getattr(v, key), (v.name, key)
        if w.type == "Enumeration":
            items = [(i.name, int(i.value)) for i in w.declaredType.items]
            assert items == [(c, k) for k, c in enumerate(codes[v.name])], v.name
    assert v3["friction_law"].declaredType.name == "FrictionLaw"
    units = {u.name: [(d.name, d.factor) for d in u.displayUnits] for u in md.unitDefinitions}
    assert {u.name: [(d.name, d.factor) for d in u.displayUnits]
            for u in md3.unitDefinitions} == units
    # ModelStructure: the same outputs and initial unknowns, by value reference
    vr = {v.name: v.valueReference for v in md.modelVariables}
    assert [u.variable.name for u in md3.outputs] == [u.variable.name for u in md.outputs]
    for u2, u3 in zip(md.initialUnknowns, md3.initialUnknowns, strict=True):
        assert u3.variable.valueReference == vr[u2.variable.name]
        assert [d.valueReference for d in u3.dependencies or []] == \
            [vr[d.name] for d in u2.dependencies or []]


def test_binaries_for_the_same_platforms_and_no_python_in_the_linux_one(fmu_path, fmu3_path,
                                                                         unzip3):
    platforms = {"linux64": "x86_64-linux", "win64": "x86_64-windows"}
    with zipfile.ZipFile(fmu_path) as z2, zipfile.ZipFile(fmu3_path) as z3:
        two = {n.split("/")[1] for n in z2.namelist()
               if n.startswith("binaries/") and n.split("/")[2].startswith("GearPair.")}
        three = {n.split("/")[1] for n in z3.namelist()
                 if n.startswith("binaries/") and n.split("/")[2].startswith("GearPair3.")}
        assert three == {platforms[p] for p in two}
        assert "binaries/x86_64-linux/GearPair_pythonfmu.so" in z3.namelist()  # engine = 1
        assert {n for n in z3.namelist() if n.startswith("resources/")} == \
            {n for n in z2.namelist() if n.startswith("resources/")}
    so = unzip3 / "binaries" / "x86_64-linux" / "GearPair3.so"
    ldd = subprocess.run(["ldd", str(so)], capture_output=True, text=True).stdout
    assert "python" not in ldd, ldd
    # every function of the FMI 3 headers is exported, and no other fmi function
    header = (Path(fmpy.__file__).parent / "c-code" / "fmi3Functions.h").read_text()
    declared = set(re.findall(r"FMI3_Export\s+\w+\s+(fmi3\w+);", header))
    nm = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True,
                        text=True).stdout
    exported = {line.split()[-1] for line in nm.splitlines()
                if " T " in line and line.split()[-1].startswith("fmi")}
    assert declared and exported == declared, (declared ^ exported)


# -- stepping: GearPair.fmu's outputs bit for bit ------------------------------------------------
def _outputs(md) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == "output"]


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_outputs_equal_gearpair_fmu_bit_for_bit(fmu_path, fmu3_path, md, scene):
    start, t_end = SCENES[scene]
    kw = dict(stop_time=t_end, output_interval=1e-4, start_values=start, output=_outputs(md))
    r2 = fmpy.simulate_fmu(str(fmu_path), **kw)
    for flags in ({}, {"use_event_mode": True}):
        r3 = fmpy.simulate_fmu(str(fmu3_path), **flags, **kw)
        assert np.array_equal(r3["time"], r2["time"])
        for name in _outputs(md):
            assert np.array_equal(r3[name], r2[name]), (scene, flags, name)
    assert len(set(r2["contact_state"])) > 1  # the scene switches contact states


# -- the state machine ---------------------------------------------------------------------------
class Slave:
    """One GearPair3 instance through fmpy's FMU3Slave, keeping its log messages."""

    def __init__(self, md3, unzip3, logging_on=False, event_mode=False, early=False):
        self.messages: list[tuple[int, str]] = []

        def log(env, status, category, message):
            self.messages.append((status, message.decode()))

        self.fmu = FMU3Slave(guid=md3.guid, unzipDirectory=str(unzip3),
                             modelIdentifier="GearPair3", instanceName="t3")
        self.fmu.instantiate(loggingOn=logging_on, eventModeUsed=event_mode,
                             earlyReturnAllowed=early, logMessage=log)
        self._log = log
        self.vr = {v.name: v.valueReference for v in md3.modelVariables}

    def refused(self, call, *args, words=()) -> str:
        n = len(self.messages)
        with pytest.raises(FMICallException) as e:
            call(*args)
        assert e.value.status == 3  # fmi3Error
        text = " ".join(m for _, m in self.messages[n:])
        for w in words:
            assert w in text, text
        return text

    def init(self, **start) -> None:
        self.fmu.enterInitializationMode(startTime=0.0)
        for name, x in start.items():
            self.fmu.setFloat64([self.vr[name]], [x])
        self.fmu.exitInitializationMode()

    def reals(self, names) -> list[float]:
        return self.fmu.getFloat64([self.vr[n] for n in names])


def test_calls_out_of_order_are_refused_with_a_message(md3, unzip3):
    s = Slave(md3, unzip3)
    f = s.fmu
    s.refused(f.doStep, 0.0, 1e-4, words=("fmi3DoStep is not allowed in Instantiated",
                                          "fmi3EnterInitializationMode"))
    s.refused(f.getFloat64, [s.vr["dte"]], words=("fmi3GetFloat64 is not allowed",))
    f.enterInitializationMode(startTime=0.0)
    s.refused(f.doStep, 0.0, 1e-4, words=("call fmi3ExitInitializationMode first",))
    f.exitInitializationMode()  # eventModeUsed false: Step Mode
    s.refused(f.enterEventMode, words=("eventModeUsed = false",))
    s.refused(f.updateDiscreteStates, words=("not allowed in Step Mode",))
    s.refused(f.enterStepMode, words=("not allowed in Step Mode",))
    s.refused(f.setFloat64, [s.vr["rtol"]], [1e-6], words=("parameter rtol is fixed",))
    s.refused(f.setFloat64, [s.vr["time"]], [1.0], words=("independent variable",))
    s.refused(f.getInt32, [s.vr["friction_law"]],
              words=("is not a Int32 variable",))
    assert f.getInt64([s.vr["friction_law"]]) == [3]
    s.refused(f.getFloat64, [12345], words=("value reference 12345",))
    s.refused(f.doStep, 0.5, 1e-4, words=("does not match the FMU's time",))
    s.refused(f.doStep, 0.0, -1e-4, words=("step size > 0",))
    s.refused(f.getFloat32, [s.vr["dte"]], words=("no Float32 variables",))
    s.refused(f.enterConfigurationMode, words=("no structural parameters",))
    assert f.getFloat32([]) == []  # no values of a type it has not: nothing to refuse
    f.doStep(0.0, 1e-4)
    assert s.reals(["time"]) == [1e-4]
    f.terminate()
    s.refused(f.doStep, 1e-4, 1e-4, words=("not allowed in Terminated",))
    assert s.reals(["dte"])[0] != 0.0  # values still readable once terminated
    f.reset()
    s.refused(f.getFloat64, [s.vr["dte"]])
    assert all(status == 3 for status, _ in s.messages)  # errors reach a logger that is off
    f.freeInstance()


def test_event_mode_after_initialization_and_between_steps(md3, unzip3):
    s = Slave(md3, unzip3, event_mode=True, early=True)
    f = s.fmu
    s.init(mu=0.06)
    s.refused(f.doStep, 0.0, 1e-4, words=("call fmi3EnterStepMode first",))
    assert f.updateDiscreteStates() == (False, False, False, False, False, 0.0)
    f.setFloat64([s.vr["torque"]], [3000.0])  # an input, in Event Mode
    f.enterStepMode()
    event, terminate, early, t_last = f.doStep(0.0, 1e-4)
    assert (terminate, t_last) == (False, 1e-4)
    f.enterEventMode()
    s.refused(f.enterEventMode, words=("in Event Mode already",))
    f.updateDiscreteStates()
    f.enterStepMode()
    f.doStep(1e-4, 1e-4)
    f.terminate()
    f.freeInstance()


def test_values_refused_before_initialization_stop_exit_initialization_mode(md3, unzip3):
    s = Slave(md3, unzip3)
    f = s.fmu
    f.enterInitializationMode(startTime=0.0)
    s.refused(f.setFloat64, [s.vr["mu"], s.vr["torque"]], [2.0, 100.0],
              words=("mu = 2 is out of range", "mu keeps its value"))
    s.refused(f.setInt64, [s.vr["friction_law"]], [9],
              words=("friction_law = 9 is out of range", "3 (stick_slip)"))
    s.refused(f.exitInitializationMode,
              words=("mu = 2 was refused at fmi3SetFloat64",
                     "torque = 100 was not taken", "friction_law = 9 was refused"))
    f.setFloat64([s.vr["mu"], s.vr["torque"]], [0.05, 100.0])
    f.setInt64([s.vr["friction_law"]], [2])
    f.exitInitializationMode()
    f.doStep(0.0, 1e-4)
    f.freeInstance()


def test_a_parameter_combination_is_refused_in_fmi3_words(md3, unzip3):
    s = Slave(md3, unzip3)
    f = s.fmu
    f.enterInitializationMode(startTime=0.0)
    f.setInt64([s.vr["dof"], s.vr["sliding"]], [1, 0])
    text = s.refused(f.exitInitializationMode, words=("fmi3ExitInitializationMode refused",))
    assert "fmi2" not in text
    f.setInt64([s.vr["sliding"]], [1])
    f.exitInitializationMode()
    f.freeInstance()


def test_fmu_states_replay_bit_for_bit_also_serialized_into_a_fresh_instance(md3, unzip3):
    s = Slave(md3, unzip3)
    f = s.fmu
    s.init(mu=0.06, rtol=1e-6)
    outs = ["dte", "mesh_force", "friction_force", "time"]
    t = 0.0
    for _ in range(20):
        f.doStep(t, 1e-4)
        t += 1e-4
    state = f.getFMUState()
    blob = f.serializeFMUState(state)
    run = []
    for k in range(30):
        f.doStep(t + k * 1e-4, 1e-4)
        run.append(s.reals(outs))
    f.setFMUState(state)
    again = []
    for k in range(30):
        f.doStep(t + k * 1e-4, 1e-4)
        again.append(s.reals(outs))
    assert again == run
    fresh = Slave(md3, unzip3)
    fresh.fmu.setFMUState(fresh.fmu.deserializeFMUState(blob))
    replay = []
    for k in range(30):
        fresh.fmu.doStep(t + k * 1e-4, 1e-4)
        replay.append(fresh.reals(outs))
    assert replay == run
    for bad in (blob[:-1], blob[:40] + bytes([blob[40] ^ 1]) + blob[41:]):
        fresh.refused(fresh.fmu.deserializeFMUState, bad, words=("not a complete, unaltered",))
    f.freeFMUState(state)
    f.freeInstance()
    fresh.fmu.freeInstance()


def test_the_reference_engine_runs_in_python_as_in_gearpair_fmu(fmu_path, fmu3_path):
    kw = dict(stop_time=5e-4, output_interval=1e-4, output=["dte", "contact_state"],
              start_values={"engine": 1, "rtol": 1e-6})
    r2 = fmpy.simulate_fmu(str(fmu_path), **kw)
    r3 = fmpy.simulate_fmu(str(fmu3_path), **kw)
    assert np.array_equal(r2["dte"], r3["dte"]) and r3["dte"][-1] != 0.0


def test_the_logger_type_is_fmi3s(md3, unzip3):
    """FMI 3's logger takes the message as it is: a '%' is not doubled."""
    s = Slave(md3, unzip3, logging_on=True)
    s.fmu.enterInitializationMode(startTime=0.0, tolerance=1e-6)
    assert any("tolerance 1e-06 is not used" in m for _, m in s.messages), s.messages
    assert isinstance(s.fmu.logMessage, fmi3LogMessageCallback)
    s.fmu.freeInstance()


# -- early return at contact events --------------------------------------------------------------
H = 1e-4
INSTANT = ("dte", "mesh_force", "friction_force", "contact_state", "output_torque",
           "input_torque_reaction", "input_torque", "gear1_speed", "gear2_speed",
           "sliding_velocity")  # the outputs of an instant (not of a step)
FRICTION = ("off", "nominal", "regularized", "stick_slip")


def _off_grid(t: np.ndarray) -> np.ndarray:
    """The rows fmpy recorded between communication points: at early returns."""
    return np.abs(t / H - np.round(t / H)) > 1e-6


def _api_event_times(start: dict, t_end: float) -> list[float]:
    """The Python API's fast engine on the same grid, without early return: the time of the
    change of the contact state in each step that has one switch, from the step's exact
    fractions in stick, apart or on the back flank."""
    from gearpair import Effects, GearParams
    from gearpair import stepblock as sb
    from gearpair.fast import FastEngine

    start = dict(start)
    torque, speed = start.pop("torque", 3900.0), start.pop("speed", 100 * RPM)
    rtol = start.pop("rtol", 1e-8)
    fx = {"friction": FRICTION[start.pop("friction_law", 3)]}
    if "backlash" in start:
        fx["backlash"] = start.pop("backlash")
    eng = FastEngine(GearParams(**start), Effects(**fx), rtol=rtol)
    eng.reset(0.0, torque, speed)
    rec = {n: sb.X_REC + k for k, n in enumerate(sb.STEP_RECORD)}
    x, times, cs0 = eng.block, [], eng.outputs().contact_state
    in_state = {2: "stick_fraction", 0: "separation_fraction", 3: "back_fraction"}
    for k in range(round(t_end / H)):
        eng.advance_values((k + 1) * H, torque, speed)
        cs = int(x[rec["contact_state"]])
        if cs != cs0 and x[rec["n_events"]] == 1:
            if cs in in_state:  # the time in the new state ends the step
                times.append((k + 1) * H - x[rec[in_state[cs]]] * H)
            else:  # into slip: the time in the old state began the step
                times.append(k * H + x[rec[in_state[cs0]]] * H)
        cs0 = cs
    return times


@pytest.mark.parametrize("scene", ["stick_slip", "contact_loss"])
def test_early_return_at_the_engines_own_event_times(fmu_path, fmu3_path, md, scene):
    start, t_end = SCENES[scene]
    kw = dict(stop_time=t_end, output_interval=H, start_values=start, output=_outputs(md))
    r2 = fmpy.simulate_fmu(str(fmu_path), **kw)
    r3 = fmpy.simulate_fmu(str(fmu3_path), early_return_allowed=True, use_event_mode=True,
                           **kw)
    off = _off_grid(r3["time"])
    rows = np.nonzero(off)[0]
    # a row at the early return and one after Event Mode, at the same time and state
    assert len(rows) >= 4 and len(rows) % 2 == 0
    assert np.array_equal(rows[1::2], rows[0::2] + 1)
    events = r3["time"][rows[0::2]]
    assert np.array_equal(events, r3["time"][rows[1::2]])
    for name in INSTANT:
        assert np.array_equal(r3[name][rows[0::2]], r3[name][rows[1::2]]), name
    # each is a change of the contact state since the row before
    cs = r3["contact_state"]
    assert all(cs[i] != cs[i - 1] for i in rows[0::2])
    # at the times the engine locates them without early return (Python API, same scene)
    api = _api_event_times(start, t_end)
    assert len(api) >= min(3, len(events))
    for te in api:
        assert np.min(np.abs(events - te)) <= 1e-12, te
    # between the events, GearPair.fmu's outputs at the same times, to rounding
    grid = r3[~off]
    assert np.array_equal(grid["time"], r2["time"])
    for name in INSTANT:
        scale = max(float(np.max(np.abs(r2[name]))), 1e-300)
        assert np.max(np.abs(grid[name] - r2[name])) <= 1e-9 * scale, name


def test_early_return_without_event_mode_goes_on_from_there(fmu3_path, md):
    """A master that allows early return and never enters Event Mode: the next step starts
    at lastSuccessfulTime and the rows are those of a master that does."""
    start, t_end = SCENES["contact_loss"]
    kw = dict(stop_time=t_end, output_interval=H, start_values=start, output=_outputs(md))
    with_event = fmpy.simulate_fmu(str(fmu3_path), early_return_allowed=True,
                                   use_event_mode=True, **kw)
    without = fmpy.simulate_fmu(str(fmu3_path), early_return_allowed=True, **kw)
    keep = np.ones(len(with_event), dtype=bool)
    keep[np.nonzero(_off_grid(with_event["time"]))[0][1::2]] = False  # the Event Mode rows
    assert np.array_equal(without["time"], with_event["time"][keep])
    for name in _outputs(md):
        assert np.array_equal(without[name], with_event[name][keep]), name


# -- a C host: two instances in two threads, no Python ----------------------------------------
HOSTS = ROOT / "examples" / "hosts"


def _host_args(md3, scene: str, mode: int, threads: int) -> list[str]:
    start, t_end = SCENES[scene]
    vr = {v.name: v.valueReference for v in md3.modelVariables}
    types = {v.name: v.type for v in md3.modelVariables}
    args = ["GearPair3", md3.guid, repr(H), repr(t_end)]
    for name, value in start.items():
        flag = {"Float64": "-r", "Int32": "-i", "Enumeration": "-e", "Boolean": "-b"}
        args += [flag[types[name]], f"{vr[name]}={value!r}"]
    reals = [n for n in INSTANT if types[n] == "Float64"]
    return args + ["-o", ",".join(str(vr[n]) for n in reals), "-n", str(vr["contact_state"]),
                   "-E", str(mode), "-j", str(threads)]


def _host_rows(text: str) -> dict[int, list[list[str]]]:
    out: dict[int, list[list[str]]] = {}
    for line in text.splitlines():
        if line.startswith("# instance "):
            rows = out.setdefault(int(line.split()[-1]), [])
        else:
            rows.append(line.split(","))
    return out


def _fmpy_rows(res) -> list[tuple]:
    reals = [n for n in INSTANT if n != "contact_state"]
    return [(float(r["time"]), *(float(r[n]) for n in reals), int(r["contact_state"]))
            for r in res]


@pytest.fixture(scope="module")
def host3(tmp_path_factory) -> Path:
    from test_hosts import compile_c_host

    return compile_c_host(HOSTS / "fmi3_host.c", tmp_path_factory.mktemp("host3") / "fmi3_host")


@pytest.mark.parametrize("scene", ["stick_slip", "contact_loss"])
def test_c_host_two_instances_in_two_threads_as_fmpy(fmu3_path, md3, unzip3, host3, scene):
    start, t_end = SCENES[scene]
    outs = list(INSTANT)
    ref = fmpy.simulate_fmu(str(fmu3_path), early_return_allowed=True, use_event_mode=True,
                            stop_time=t_end, output_interval=H, start_values=start,
                            output=outs)
    proc = subprocess.run([str(host3), str(unzip3), *_host_args(md3, scene, 1, 2)],
                          env={"PATH": "/usr/bin:/bin"}, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    runs = _host_rows(proc.stdout)
    assert sorted(runs) == [0, 1] and runs[0] == runs[1]  # threads: the same bits
    kinds = [r[0] for r in runs[0]]
    assert kinds[0] == "init" and "early" in kinds and kinds.count("early") == \
        kinds.count("event")
    got = [(float(r[1]), *(float(x) for x in r[2:-1]), int(r[-1])) for r in runs[0]]
    assert got == _fmpy_rows(ref)  # every row, early returns included, bit for bit


def test_the_windows_binary_under_wine_prints_the_linux_bits(md3, unzip3, host3, tmp_path,
                                                            wine):
    """The x86_64-windows binary (when the build had mingw-w64): the same host built for
    Windows, under Wine, prints what it prints with the Linux binary, early returns and
    threads included."""
    if not (unzip3 / "binaries" / "x86_64-windows" / "GearPair3.dll").is_file():
        pytest.skip("GearPair3.fmu has no x86_64-windows binary (no mingw-w64 at the build)")
    exe = compile_win64_host(HOSTS / "fmi3_host.c", tmp_path / "fmi3_host.exe")
    args = _host_args(md3, "contact_loss", 1, 2)
    lin = subprocess.run([str(host3), str(unzip3), *args], env={"PATH": "/usr/bin:/bin"},
                         capture_output=True, text=True, timeout=120)
    win = wine(exe, winpath(unzip3), *args)
    assert lin.returncode == 0 and win.returncode == 0, win.stderr[-2000:]
    assert "early" in win.stdout and win.stdout == lin.stdout
