"""The FMU's native step (the C layer runs the compiled step without Python) against its
Python path (``GEARPAIR_NATIVE_STEP=0``: every call through pythonfmu into the slave): the
same call sequence through the built FMU gives bit-identical values of every variable after
every call, refusals, failed steps and state restores included; and the slave's own getters
and setters."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
pytest.importorskip("numba")

from fmu_slave import LoggingSlave  # noqa: E402

pytestmark = pytest.mark.fmu
RPM = 2.0 * math.pi / 60.0


@pytest.fixture(scope="module")
def slave_class(fmu_path, tmp_path_factory):
    unzip = Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp_path_factory.mktemp("path"))))
    spec = importlib.util.spec_from_file_location("_gearpair_step_path_slave",
                                                  unzip / "resources" / "GearPair.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.GearPair, str(unzip / "resources")


def _sequence(md, unzip, load_speed_input: bool) -> tuple[list, int]:
    """Run one instance through a fixed call sequence; (every value after every call, the
    number of doSteps the slave's Python ``do_step`` took)."""
    g = LoggingSlave(md, unzip, name="seq", logging_on=False)
    f, vr = g.fmu, g.vr
    reals = [v.valueReference for v in md.modelVariables if v.type == "Real"]
    ints = [v.valueReference for v in md.modelVariables if v.type == "Integer"]
    cls = sys.modules["GearPair"].GearPair  # the slave class pythonfmu imported
    calls = {"n": 0}
    python_step = cls.do_step

    def counted(self, t, h):
        calls["n"] += 1
        return python_step(self, t, h)

    def values():
        return (tuple(x.hex() for x in f.getReal(reals)), tuple(f.getInteger(ints)))

    cls.do_step = counted
    try:
        out = []
        f.setupExperiment(startTime=0.0)
        f.setBoolean([vr["load_speed_input"]], [load_speed_input])
        vin = [vr["torque"], vr["speed"], vr["load_speed"]]
        f.setReal(vin, [3900.0, 100 * RPM, 100 * RPM / 1.5])
        f.enterInitializationMode()
        f.exitInitializationMode()
        out.append(values())
        t = t_saved = t_blob = 0.0
        saved = blob = None
        for k in range(80):
            h = (1e-4, 3e-4, 1e-3)[k % 3]
            u = [3900.0 + 40.0 * k, (100 + k) * RPM, (100 + k) * RPM / 1.5]
            if k == 10:
                u[0] = math.nan  # refused by the C layer: the old torque is kept
            try:
                f.setReal(vin, u)
                out.append("set")
            except fmpy.fmi1.FMICallException:
                out.append(("refused", values()))
            if k == 15:
                saved, t_saved = f.getFMUstate(), t
            if k == 30:
                blob, t_blob = f.serializeFMUstate(f.getFMUstate()), t
            try:
                f.doStep(t if k != 20 else t + 1.0, h)  # k = 20: a wrong time, refused
                ok = True
                t += h
            except fmpy.fmi1.FMICallException:
                ok = False
            out.append((ok, values()))
            if k == 45:  # back to the state saved at k = 15
                f.setFMUstate(saved)
                t = t_saved
                out.append(values())
            if k == 60:  # and to the state serialized at k = 30
                f.setFMUstate(f.deSerializeFMUstate(blob))
                t = t_blob
                out.append(values())
        f.terminate()
        f.freeInstance()
        return out, calls["n"]
    finally:
        cls.do_step = python_step


@pytest.mark.parametrize("load_speed_input", [False, True])
def test_native_step_is_bit_identical_to_python_path(fmu_path, md, tmp_path, monkeypatch,
                                                     load_speed_input):
    unzip = fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "fmu"))
    monkeypatch.setenv("GEARPAIR_NATIVE_STEP", "1")
    native, native_calls = _sequence(md, unzip, load_speed_input)
    monkeypatch.setenv("GEARPAIR_NATIVE_STEP", "0")
    python, python_calls = _sequence(md, unzip, load_speed_input)
    assert native == python
    steps = [r for r in native if isinstance(r, tuple) and isinstance(r[0], bool)]
    assert sum(ok for ok, _ in steps) == 79  # all but the one at a wrong time
    # Python stepped every step on its path; natively only the first, the refused one and
    # the first after each restored state
    assert python_calls == 80
    assert native_calls <= 5, native_calls
    names = [v.name for v in md.modelVariables if v.type == "Real"]
    stick = [float.fromhex(r[names.index("stick_fraction")]) for _, (r, _) in steps]
    assert max(stick) > 0.1  # the compared steps include stick-slip switches


def test_getters_fall_back_to_pythonfmu(slave_class):
    """A parameter set through set_real keeps its setter (the engine is rebuilt); a value
    reference of another type is refused as pythonfmu refuses it."""
    cls, resources = slave_class
    s = cls(instance_name="p", resources=resources)
    vr = {v.name: k for k, v in s.vars.items()}
    s.set_real([vr["rtol"]], [1e-7])
    assert s.rtol == 1e-7 and s._params_set
    with pytest.raises(TypeError):
        s.get_real([vr["contact_state"]])
    with pytest.raises(TypeError):
        s.get_integer([vr["dte"]])
    with pytest.raises(TypeError):
        s.set_real([vr["contact_state"]], [1.0])
    assert s.get_real([vr["torque"], vr["rtol"]]) == [s.torque, 1e-7]


def test_two_instances_in_two_threads_of_a_c_host(fmu_path, tmp_path):
    """Two instances stepped at once from two threads of one C process (no interpreter lock
    per step) give the outputs of the same two stepped one after the other, and of one
    instance stepped from a worker thread or the instantiating thread, also with every
    mode interleaved round by round in one process."""
    from gearpair.bench import chost

    host, why = chost.build_host(tmp_path)
    if host is None:
        pytest.skip(why)
    unit = chost.extract(fmu_path, tmp_path / "fmu")
    start = chost.fmu_start(fmu_path, chost.REGIME, 1e-8)
    got = {m: chost.run_host(host, unit, start, 1e-4, 300, 2, threads=m)
           for m in (*chost.THREAD_MODES, "interleaved")}
    digests = {m: [i["digest"] for i in g["instances"]] for m, g in got.items()}
    assert len(digests["pair"]) == len(digests["serial"]) == 2
    # interleaved: every mode in each round; its last instance, the floor, steps 10 x 1e-4 s;
    # a forked copy of the host steps its copy of the twin (the one before the floor)
    assert len(digests["interleaved"]) == 7
    assert digests["interleaved"].pop() != digests["main"][0]
    digests["forked copy"] = [got["interleaved"]["rounds"]["twin_digest"]]
    assert {d for ds in digests.values() for d in ds} == {digests["main"][0]}, digests
    assert all(g["exit_status"] == 0 for g in got.values())
    # the outputs moved: the digest is of a stick-slip run, not of constants
    assert got["main"]["last_output"] != 0.0


def test_a_state_restored_into_another_instance_steps_natively(fmu_path, md, tmp_path):
    """A serialized state set into a second instance: it goes on with the first one's
    outputs, and after one step through Python the C layer steps it natively."""
    unzip = fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "fmu"))
    a, b = (LoggingSlave(md, unzip, name=n, logging_on=False) for n in ("a", "b"))
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output"
            and v.type == "Real"]
    for g in (a, b):
        g.fmu.setupExperiment(startTime=0.0)
        g.fmu.enterInitializationMode()
        g.fmu.exitInitializationMode()
    for k in range(5):
        a.fmu.doStep(k * 1e-4, 1e-4)
    b.fmu.setFMUstate(b.fmu.deSerializeFMUstate(a.fmu.serializeFMUstate(a.fmu.getFMUstate())))
    cls = sys.modules["GearPair"].GearPair
    calls = {"n": 0}
    python_step = cls.do_step

    def counted(self, t, h):
        calls["n"] += 1
        return python_step(self, t, h)

    cls.do_step = counted
    try:
        for k in range(5, 25):
            for g in (a, b):
                g.fmu.doStep(k * 1e-4, 1e-4)
            assert a.fmu.getReal(outs) == b.fmu.getReal(outs)
    finally:
        cls.do_step = python_step
    assert calls["n"] == 1  # b's first step after the restore
    for g in (a, b):
        g.fmu.terminate()
        g.fmu.freeInstance()
