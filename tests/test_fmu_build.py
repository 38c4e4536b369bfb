"""Build the GearPair FMU once and check its model description, resources and behaviour."""

from __future__ import annotations

import importlib.util
import math
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

from fmpy import extract  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import (  # noqa: E402
    fmi2Error,
    fmi2Warning,
)
from fmpy.validation import validate_fmu  # noqa: E402
from fmu_slave import LoggingSlave  # noqa: E402

pytestmark = pytest.mark.fmu

ROOT = Path(__file__).resolve().parents[1]
RPM = 2.0 * math.pi / 60.0


@pytest.fixture(scope="module")
def unzipdir(fmu_path, tmp_path_factory) -> str:
    return str(extract(str(fmu_path), unzipdir=str(tmp_path_factory.mktemp("unzip"))))


class Instance(LoggingSlave):
    """An FMU2Slave with a logger that keeps the messages (debug logging on)."""

    OUTPUTS = ("dte", "mesh_force", "friction_force", "output_torque", "input_torque_reaction",
               "gear1_speed", "gear2_speed", "sliding_velocity", "stick_fraction",
               "separation_fraction", "mesh_force_max")

    initialized = False

    def initialize(self, t0: float = 0.0, **start) -> None:
        self.fmu.setupExperiment(startTime=t0)
        self.set(**start)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.initialized = True

    def outputs(self) -> tuple:
        reals = self.fmu.getReal([self.vr[n] for n in self.OUTPUTS])
        ints = self.fmu.getInteger([self.vr["contact_state"], self.vr["n_events"]])
        return tuple(reals) + tuple(ints)

    def steps(self, t: float, h: float, n: int) -> tuple[float, list[tuple]]:
        rows = []
        for _ in range(n):
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            t += h
            rows.append(self.outputs())
        return t, rows

    def close(self) -> None:
        if self.initialized:  # fmi2Terminate is allowed only after initialization
            self.fmu.terminate()
        self.fmu.freeInstance()


FAST = {"rtol": 1e-6}  # looser tolerance for quick behavioural tests


# -- model description ----------------------------------------------------------------------
def test_validate_finds_no_problems(fmu_path):
    assert validate_fmu(str(fmu_path)) == []


def test_units_ranges_and_flags(md):
    v = {x.name: x for x in md.modelVariables}
    assert (v["torque"].unit, v["torque"].min, v["torque"].max) == ("N.m", "-1000000.0",
                                                                    "1000000.0")
    assert v["torque"].causality == "input" and float(v["torque"].start) == 3900.0
    assert (v["speed"].unit, v["speed"].displayUnit) == ("rad/s", "rpm")
    assert float(v["speed"].start) == pytest.approx(100 * RPM, rel=1e-15)
    assert (v["dte"].unit, v["dte"].displayUnit) == ("m", "um")
    assert (v["mesh_force"].unit, v["mesh_force"].displayUnit) == ("N", "kN")
    assert (v["gear2_speed"].unit, v["gear2_speed"].displayUnit) == ("rad/s", "rpm")
    assert (v["m1"].unit, float(v["m1"].min), float(v["m1"].max)) == ("kg", 0.0, 1e5)
    assert v["m1"].causality == "parameter" and v["m1"].variability == "fixed"
    assert v["pressure_angle"].displayUnit == "deg"
    assert (v["z1"].type, v["z1"].min, v["z1"].max) == ("Integer", "12", "400")
    assert (v["stiffness_model"].type, v["stiffness_model"].min, v["stiffness_model"].max) == (
        "Integer", "0", "2")
    assert (v["friction_law"].start, v["friction_law"].max) == ("3", "3")
    assert v["separation"].type == "Boolean" and v["separation"].variability == "fixed"
    assert (float(v["rtol"].min), float(v["rtol"].max), float(v["rtol"].start)) == (
        1e-12, 1e-3, 1e-8)
    for name in ("contact_state", "n_events"):
        assert v[name].type == "Integer" and v[name].variability == "discrete"
    assert all(x.description for x in md.modelVariables)

    units = {u.name: u for u in md.unitDefinitions}
    rpm = {d.name: d for d in units["rad/s"].displayUnits}["rpm"]
    assert rpm.factor == pytest.approx(60 / (2 * math.pi))
    assert (units["N"].baseUnit.kg, units["N"].baseUnit.m, units["N"].baseUnit.s) == (1, 1, -2)

    cs = md.coSimulation
    assert cs.canHandleVariableCommunicationStepSize
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    de = md.defaultExperiment
    assert (de.startTime, de.stopTime, de.stepSize) == ("0", "0.5", "0.0001")

    inputs = {v["torque"], v["speed"], v["load_speed"]}
    outputs = [x for x in md.modelVariables if x.causality == "output"]
    assert {u.variable for u in md.outputs} == set(outputs)
    assert len(inputs) == 3


def test_outputs_declared_and_found_independent_of_inputs(md, unzipdir):
    """<ModelStructure> declares no output directly dependent on an input, and that is what
    the FMU does: after fmi2SetReal of every input, fmi2GetReal/Integer return the same
    values until the next fmi2DoStep (which the new inputs then do change). A declared
    dependency that is not real makes masters report algebraic loops in feedback systems."""
    inputs = {"torque": 1000.0, "speed": 50 * RPM, "load_speed": 20 * RPM}
    declared = {u.variable.name: {d.name for d in u.dependencies} for u in md.outputs}
    outputs = [x for x in md.modelVariables if x.causality == "output"]
    assert set(declared) == {x.name for x in outputs}

    def read(g):
        return {x.name: (g.fmu.getReal if x.type == "Real" else g.fmu.getInteger)(
            [x.valueReference])[0] for x in outputs}

    runs = []
    for changed in (False, True):
        g = Instance(md, unzipdir)
        try:
            g.initialize(**FAST, load_speed_input=True)
            g.steps(0.0, 1e-4, 2)
            before = read(g)
            if changed:
                g.set(**inputs)
            after = read(g)
            for name in declared:
                moved = after[name] != before[name]
                assert moved == bool(declared[name] & set(inputs)), (name, declared[name])
            g.fmu.doStep(2e-4, 1e-4)
            runs.append(read(g))
        finally:
            g.close()
    # the inputs do act, through the step
    assert runs[0]["mesh_force"] != runs[1]["mesh_force"]
    assert runs[0]["gear2_speed"] != runs[1]["gear2_speed"]


def test_initial_outputs_declared_and_found_independent_of_load_speed(md, unzipdir):
    """<InitialUnknowns> lists torque and speed (and the parameters), not load_speed, for
    every output: the static equilibrium of fmi2ExitInitializationMode does not use it, so
    a master feeding load_speed back sees no loop at initialization."""
    names = {i: v.name for i, v in enumerate(md.modelVariables, start=1)}
    declared = {u.variable.name: {d.name for d in u.dependencies} for u in md.initialUnknowns}
    assert declared["mesh_force"] >= {"torque", "speed", "mu"}
    assert all("load_speed" not in deps for deps in declared.values())
    assert set(names.values()) >= set(declared)
    outputs = [x for x in md.modelVariables if x.causality == "output"]

    def initial(**inputs):
        g = Instance(md, unzipdir)
        try:
            g.initialize(**FAST, load_speed_input=True, **inputs)
            return [(g.fmu.getReal if x.type == "Real" else g.fmu.getInteger)(
                [x.valueReference])[0] for x in outputs]
        finally:
            g.close()

    base = initial(load_speed=0.0)
    assert initial(load_speed=30 * RPM) == base
    assert initial(torque=1000.0) != base


def test_parameters_match_gearparams(md):
    """Every GearParams field is a parameter with the field's unit and range."""
    spec = importlib.util.spec_from_file_location(
        "_gp_params", ROOT / "model" / "gearpair" / "params.py")
    params = importlib.util.module_from_spec(spec)
    sys.modules["_gp_params"] = params  # dataclasses look their module up
    try:
        spec.loader.exec_module(params)
    finally:
        del sys.modules["_gp_params"]
    v = {x.name: x for x in md.modelVariables}
    for row in params.GearParams.describe():
        var = v[row["name"]]
        assert var.causality == "parameter" and var.initial == "exact"
        assert float(var.min) == row["min"] and float(var.max) == row["max"]
        assert float(var.start) == row["default"]
        if var.type == "Real":
            assert var.unit == row["unit"]


def _builder():
    spec = importlib.util.spec_from_file_location("_build_fmu_check", ROOT / "build_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_resources_and_documentation(fmu_path):
    with zipfile.ZipFile(fmu_path) as z:
        names = set(z.namelist())
        req = z.read("resources/requirements.txt").decode()
        doc = z.read("documentation/index.html").decode()
    for f in ("__init__.py", "engine.py", "params.py", "effects.py", "reference.py"):
        assert f"resources/gearpair/{f}" in names
    assert not any("__pycache__" in n for n in names)
    assert "resources/GearPair.py" in names
    # the C layer and pythonfmu's library beside it, the C layer for Windows where mingw-w64
    # is (test_win64.py); no binary for a platform not built
    win64 = {"binaries/win64/GearPair.dll"} if _builder().win64_compiler() else set()
    assert {n for n in names if n.startswith("binaries/")} == {
        "binaries/linux64/GearPair.so", "binaries/linux64/GearPair_pythonfmu.so"} | win64
    assert "numpy" in req and "scipy" in req
    # the bundled package's requirements are pyproject.toml's, with the tested bounds
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert req.splitlines() == project["dependencies"]
    assert any(r.startswith("numba>=") and ",<" in r for r in req.splitlines())
    for word in ("torque", "mesh_force", "stick_fraction", "friction_law", "stiffness_model",
                 "rtol", "Eq. (14)", "rpm"):
        assert word in doc


# -- behaviour ------------------------------------------------------------------------------
def test_simulate_fmu_gives_finite_outputs(fmu_path):
    res = fmpy.simulate_fmu(str(fmu_path), stop_time=3e-3, output_interval=1e-3,
                            start_values=dict(FAST))
    assert len(res) == 4 and res["time"][-1] == pytest.approx(3e-3)
    for name in res.dtype.names:
        assert all(math.isfinite(x) for x in res[name]), name
    assert set(res["contact_state"]) <= {0, 1, 2}
    assert 30e3 < res["mesh_force"][0] < 60e3  # static mesh force near 42 kN
    assert res["gear1_speed"][0] == pytest.approx(100 * RPM)


def test_fmu_imports_its_bundled_package_and_exits_cleanly(fmu_path, tmp_path):
    """Two copies of the FMU in one Python host, both running the reference engine (the one in
    Python), the first one's folder deleted: the second imports its own bundled package
    under the private name, the host's ``sys.path`` and
    ``gearpair`` stay its own (importing gearpair afterwards works and finds the host's
    package, not a deleted copy), and the interpreter's normal teardown ends with status 0
    (the FMU's C layer empties pythonfmu's static interpreter guard, which pythonfmu's exit
    code would otherwise release twice)."""
    code = textwrap.dedent(f"""
        import os, sys
        from fmpy import extract, read_model_description, simulate_fmu
        from fmpy.fmi2 import FMU2Slave
        path0 = list(sys.path)
        simulate_fmu({str(fmu_path)!r}, stop_time=1e-3, output_interval=1e-3,
                     start_values={{"engine": 1}})
        md = read_model_description({str(fmu_path)!r})
        d = extract({str(fmu_path)!r})
        s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier="GearPair",
                      instanceName="x")
        s.instantiate()
        vr = {{v.name: v.valueReference for v in md.modelVariables}}
        s.setupExperiment(startTime=0.0); s.enterInitializationMode()
        s.setInteger([vr["engine"]], [1]); s.exitInitializationMode()
        print(sys.modules["_gearpair_fmu"].__file__.startswith(str(d)),
              "gearpair" in sys.modules, sys.path == path0, flush=True)
        s.freeInstance()
        import gearpair.scenes
        print(gearpair.scenes.__file__.startswith({str(ROOT / "model")!r}), flush=True)
    """)
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", "False", "True", "True"]


def test_an_instance_freed_with_a_message_pending_exits_cleanly(fmu_path, tmp_path):
    """Found by the host tests: a Python slave whose constructor logged (here the warning of a
    second copy of the FMU running the first one's package) and that is freed without any
    other call crashed pythonfmu's destructor (SIGSEGV). The C layer delivers such messages
    when it creates the slave (the reference engine's initialization), so the warning
    arrives at once and the process exits with 0."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT / "tests")!r})
        import fmpy
        from fmu_slave import LoggingSlave
        fmu = {str(fmu_path)!r}
        md = fmpy.read_model_description(fmu)
        first = LoggingSlave(md, fmpy.extract(fmu, unzipdir={str(tmp_path / "a")!r}), "first")
        second = LoggingSlave(md, fmpy.extract(fmu, unzipdir={str(tmp_path / "b")!r}), "second")
        for g in (first, second):  # the reference engine: its slave starts at initialization
            g.fmu.setupExperiment(startTime=0.0); g.fmu.enterInitializationMode()
            g.fmu.setInteger([g.vr["engine"]], [1]); g.fmu.exitInitializationMode()
        warned = [sum(st >= 1 for st, _ in g.messages) for g in (first, second)]  # warning+
        print(*warned, flush=True)
        second.fmu.freeInstance()
        first.fmu.freeInstance()
    """)
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split() == ["0", "1"]


def test_a_copy_from_another_live_folder_says_which_package_it_runs(fmu_path, md, unzipdir,
                                                                   tmp_path):
    """Instances of the reference engine in one process share the bundled package while its
    folder exists; a copy
    of the FMU extracted elsewhere then runs it, and its log names the folder it came from
    (a silent swap could hide a version mismatch between two FMU files)."""
    first = Instance(md, unzipdir)
    other = Instance(md, str(extract(str(fmu_path), unzipdir=str(tmp_path / "other"))))
    try:
        for g in (first, other):  # the reference engine: the slave runs in Python
            g.initialize(**FAST, engine=1)
        loaded = os.path.dirname(sys.modules["_gearpair_fmu"].__file__)
        assert not loaded.startswith(str(tmp_path))
        said = [m for st, m in other.messages if st == fmi2Warning]
        assert any(loaded in m and "resources" in m for m in said), other.messages
    finally:
        other.close()
        first.close()


def _reference_rows(md, unzipdir, n: int, **start) -> list[tuple]:
    """Outputs after each of n steps of 1e-4 s of an instance never given a bad call."""
    ref = Instance(md, unzipdir, "ref")
    ref.initialize(**FAST, **start)
    _, rows = ref.steps(0.0, 1e-4, n)
    ref.close()
    return rows


def test_nan_input_is_refused_when_set_and_the_old_value_kept(md, unzipdir):
    g = Instance(md, unzipdir)
    g.initialize(**FAST)
    t, rows = g.steps(0.0, 1e-4, 2)
    with pytest.raises(FMICallException) as exc:
        g.set(torque=math.nan)
    assert exc.value.status == fmi2Error
    status, msg = g.messages[-1]
    assert status == fmi2Error and "torque" in msg and "not finite" in msg and "N.m" in msg
    assert g.outputs() == rows[-1]  # state unchanged
    assert g.fmu.getReal([g.vr["torque"]]) == [3900.0]  # old value kept
    _, more = g.steps(t, 1e-4, 1)  # the next step as if nothing had happened
    assert rows + more == _reference_rows(md, unzipdir, 3)
    g.close()


def test_bad_communication_point_and_step_size_are_refused(md, unzipdir):
    g = Instance(md, unzipdir)
    g.initialize(**FAST)
    t, rows = g.steps(0.0, 1e-4, 1)
    for cp, h in ((t + 1e-3, 1e-4), (t, 0.0), (t, -1e-4), (t, math.nan), (math.inf, 1e-4)):
        with pytest.raises(FMICallException) as exc:
            g.fmu.doStep(currentCommunicationPoint=cp, communicationStepSize=h)
        assert exc.value.status == fmi2Error
        assert g.outputs() == rows[-1]
    assert "does not match" in g.messages[-5][1]
    assert all("step size > 0" in m for _, m in g.messages[-4:])
    _, more = g.steps(t, 1e-4, 1)
    assert rows + more == _reference_rows(md, unzipdir, 2)
    g.close()


@pytest.mark.parametrize("start, words", [
    ({"m1": -1.0}, ("m1", "(0, 100000] kg")),
    ({"friction_law": 7}, ("friction_law", "3 (stick_slip)")),
    ({"rtol": 0.5}, ("rtol", "0.001")),
    ({"z1": 5}, ("z1", "[12, 400]")),
    ({"mu_static": 1.5}, ("mu_static", "[0, 1]")),
    ({"stribeck_velocity": -0.1}, ("stribeck_velocity", "[0, 1] m/s")),
])
def test_out_of_range_parameter_is_refused_when_set(md, unzipdir, start, words):
    g = Instance(md, unzipdir)
    g.fmu.setupExperiment(startTime=0.0)
    with pytest.raises(FMICallException) as exc:
        g.set(**start)
    assert exc.value.status == fmi2Error
    status, msg = g.messages[-1]
    assert status == fmi2Error and all(w in msg for w in words), msg
    g.fmu.enterInitializationMode()
    (name,) = start
    default = float(next(v.start for v in md.modelVariables if v.name == name))
    get = g.fmu.getInteger if isinstance(start[name], int) else g.fmu.getReal
    assert get([g.vr[name]]) == [default]  # the refused value was never taken
    with pytest.raises(FMICallException):  # and is remembered until a valid one is set
        g.fmu.exitInitializationMode()
    assert f"{name} = " in g.messages[-1][1] and "was refused" in g.messages[-1][1]
    g.set(**{name: type(start[name])(default), **FAST})  # rtol: FAST's
    g.fmu.exitInitializationMode()
    g.initialized = True
    _, rows = g.steps(0.0, 1e-4, 2)
    assert rows == _reference_rows(md, unzipdir, 2)
    g.close()


@pytest.mark.parametrize("start, words", [
    # each value in range, together refused: below the kinetic mu, a law without static
    # friction
    ({"mu_static": 0.01}, ("mu_static", "[mu, 1] = [0.02, 1]")),
    ({"mu_static": 0.04, "friction_law": 1, "engine": 1}, ("mu_static", "'nominal'")),
])
def test_parameter_combination_is_refused_at_exit_initialization_mode(md, unzipdir, start,
                                                                      words):
    """Taken when set, refused by fmi2ExitInitializationMode (fmi2Error, the message names
    the parameter); after fmi2Reset the instance initializes and steps as a new one."""
    g = Instance(md, unzipdir)
    g.fmu.setupExperiment(startTime=0.0)
    g.set(**FAST, **start)
    g.fmu.enterInitializationMode()
    with pytest.raises(FMICallException) as exc:
        g.fmu.exitInitializationMode()
    assert exc.value.status == fmi2Error
    status, msg = g.messages[-1]
    assert status == fmi2Error and all(w in msg for w in words), msg
    g.fmu.reset()
    g.initialize(**FAST)
    _, rows = g.steps(0.0, 1e-4, 2)
    assert rows == _reference_rows(md, unzipdir, 2)
    g.close()


def test_out_of_range_parameter_via_simulate_fmu(fmu_path, capfd):
    """fmpy's simulate_fmu without debug logging: the error reaches fmpy's default logger
    (which prints it) and the simulation stops with the error instead of returning a result
    of zeros. (No ``logger=`` here: fmpy keeps the last such logger in a process-wide proxy,
    which later FMU messages would reach after this test freed it.)"""
    with pytest.raises(FMICallException) as exc:
        fmpy.simulate_fmu(str(fmu_path), stop_time=1e-3, output_interval=1e-3,
                          start_values={"kb1": 1e20})
    assert exc.value.status == fmi2Error
    out = capfd.readouterr().out
    assert "kb1 = 1e+20 N/m is out of range" in out, out


def test_static_friction_parameters_run_the_reference_engine(md, unzipdir):
    """mu_static and stribeck_velocity reach the engine: the FMU's steps equal the reference
    engine's bit for bit; their start value 0 means "equal to mu" and "off"."""
    v = {x.name: x for x in md.modelVariables}
    for name, unit in (("mu_static", "1"), ("stribeck_velocity", "m/s")):
        assert (v[name].unit, float(v[name].min), float(v[name].max), float(v[name].start)) \
            == (unit, 0.0, 1.0, 0.0)
        assert v[name].causality == "parameter" and v[name].variability == "fixed"
    assert "0: equal to mu" in v["mu_static"].description
    g = Instance(md, unzipdir)
    g.initialize(**FAST, engine=1, mu_static=0.04, stribeck_velocity=0.01)
    _, rows = g.steps(0.0, 1e-3, 5)
    assert not any(s >= fmi2Error for s, _ in g.messages), g.messages
    g.close()
    from gearpair import Effects, GearParams, make_engine

    eng = make_engine(GearParams(), Effects(mu_static=0.04, stribeck_velocity=0.01),
                      "reference", rtol=1e-6)
    eng.reset(0.0, 3900.0, 100 * RPM)
    for i, row in enumerate(rows):
        s = eng.advance((i + 1) * 1e-3, 3900.0, 100 * RPM)
        o = eng.outputs()
        assert row[:3] == (o.dte, o.mesh_force, o.friction_force)
        assert row[8] == s.stick_fraction


def test_get_set_fmu_state_round_trip(md, unzipdir):
    g = Instance(md, unzipdir)
    g.initialize(**FAST)
    t, _ = g.steps(0.0, 1e-4, 3)
    state = g.fmu.getFMUstate()
    _, first = g.steps(t, 1e-4, 3)
    g.fmu.setFMUstate(state)
    _, again = g.steps(t, 1e-4, 3)
    assert again == first  # bit-identical
    g.fmu.setFMUstate(state)  # a state can be set more than once
    _, third = g.steps(t, 1e-4, 3)
    assert third == first
    g.fmu.freeFMUstate(state)
    g.close()


def test_serialized_state_restores_in_a_fresh_instance(md, unzipdir):
    g = Instance(md, unzipdir, "a")
    g.initialize(**FAST, torque=2500.0)
    t, _ = g.steps(0.0, 1e-4, 3)
    state = g.fmu.getFMUstate()
    blob = g.fmu.serializeFMUstate(state)
    g.fmu.freeFMUstate(state)
    _, first = g.steps(t, 1e-4, 3)
    g.close()

    # a fresh instance with default parameters: the state brings rtol and torque along
    for initialize in (True, False):
        h = Instance(md, unzipdir, "b")
        if initialize:
            h.initialize()
        s2 = h.fmu.deSerializeFMUstate(blob)
        h.fmu.setFMUstate(s2)
        h.fmu.freeFMUstate(s2)
        assert h.fmu.getReal([h.vr["torque"], h.vr["rtol"]]) == [2500.0, 1e-6]
        _, again = h.steps(t, 1e-4, 3)
        assert again == first
        assert not any(s >= fmi2Error for s, _ in h.messages), h.messages
        h.close()


def test_corrupt_serialized_state_is_rejected_without_crash(md, unzipdir):
    """A state blob that does not come from this FMU is refused with fmi2Error and changes
    nothing: without the C layer's trailer at the format check; with a valid trailer around
    bytes of another shape by the model part; and, for the reference engine, a crafted
    pickle inside a valid state by the slave's restricted unpickler, which never runs its
    code."""
    import pickle
    import struct
    import zlib

    class Sneaky:
        def __reduce__(self):
            return (print, ("this must not run",))

    def sealed(payload: bytes) -> bytes:
        head = payload + b"GPFMUST2" + (2).to_bytes(4, "little") + \
            len(payload).to_bytes(4, "little")
        return head + zlib.crc32(head).to_bytes(4, "little")

    for engine in (0, 1):
        g = Instance(md, unzipdir)
        g.initialize(**FAST, engine=engine)
        t, rows = g.steps(0.0, 1e-4, 1)
        good = g.fmu.serializeFMUstate(g.fmu.getFMUstate())
        payload = pickle.dumps({"format": "gearpair-fmu-state/1", "values": {"x": Sneaky()}})
        with pytest.raises(FMICallException) as exc:
            g.fmu.deSerializeFMUstate(payload)
        assert exc.value.status == fmi2Error and "checksum" in g.messages[-1][1]
        model = 8 * (3 + len(md.modelVariables))  # the model's bytes after mode, times, values
        tag = 1.0 if engine == 0 else 2.0
        assert struct.unpack_from("<d", bytes(good), model)[0] == tag
        crafted = [bytes(good[:model]) + b"\0" * 24]  # a model state of another shape
        if engine == 1:  # the slave's pickle replaced by one that would run code
            crafted.append(bytes(good[:model + 16]) + payload)
        for blob in crafted:
            s = g.fmu.deSerializeFMUstate(sealed(blob))
            with pytest.raises(FMICallException) as exc:
                g.fmu.setFMUstate(s)
            assert exc.value.status == fmi2Error and g.messages[-1][0] == fmi2Error
            g.fmu.freeFMUstate(s)
        if engine == 1:
            assert "not allowed" in g.messages[-1][1], g.messages[-1]
        else:
            assert "another interface" in g.messages[-1][1], g.messages[-1]
        assert g.outputs() == rows[-1]
        _, more = g.steps(t, 1e-4, 1)
        assert rows + more == _reference_rows(md, unzipdir, 2, engine=engine)
        g.close()


def test_back_flank_contact_at_t0_is_not_counted_as_separation(md, unzipdir):
    """Before the first step the figures describe the instant t0: a pair pressed on its back
    flanks (negative torque through the clearance) is in contact, as the engine's
    ``separation_fraction`` counts it over a step."""
    g = Instance(md, unzipdir)
    g.initialize(**FAST, separation=True, backlash=1e-4, torque=-3900.0)
    out = dict(zip(Instance.OUTPUTS + ("contact_state", "n_events"), g.outputs(), strict=True))
    assert out["contact_state"] == 3 and out["mesh_force"] < 0.0
    assert out["separation_fraction"] == 0.0
    _, rows = g.steps(0.0, 1e-4, 1)
    assert rows[-1][Instance.OUTPUTS.index("separation_fraction")] == 0.0
    g.close()
