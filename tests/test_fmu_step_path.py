"""The FMU's step in C (the engine compiled into its binary) against the Python API's fast
engine: the same call sequence, refusals, failed steps and state restores included, gives
bit-identical outputs after every step; and instances in threads."""

from __future__ import annotations

import math

import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
pytest.importorskip("numba")

from fmu_slave import LoggingSlave  # noqa: E402

pytestmark = pytest.mark.fmu
RPM = 2.0 * math.pi / 60.0


SCHEDULE = [((1e-4, 3e-4, 1e-3)[k % 3], 3900.0 + 40.0 * k, (100 + k) * RPM) for k in range(80)]


def _fmu_sequence(md, unzip, load_speed_input: bool) -> list:
    """One FMU instance through a fixed call sequence: the outputs (hex) after each step
    taken, None for a refused call."""
    g = LoggingSlave(md, unzip, name="seq", logging_on=False)
    f, vr = g.fmu, g.vr
    outs = [vr[n] for n in STEP_OUTPUTS]
    f.setupExperiment(startTime=0.0)
    f.setBoolean([vr["load_speed_input"]], [load_speed_input])
    vin = [vr["torque"], vr["speed"], vr["load_speed"]]
    f.setReal(vin, [3900.0, 100 * RPM, 100 * RPM / 1.5])
    f.enterInitializationMode()
    f.exitInitializationMode()
    out = [tuple(x.hex() for x in f.getReal(outs))]
    t = t_saved = t_blob = 0.0
    saved = blob = None
    for k, (h, torque, speed) in enumerate(SCHEDULE):
        u = [math.nan if k == 10 else torque, speed, speed / 1.5]
        try:  # k = 10: refused by the C layer, the old torque is kept
            f.setReal(vin, u)
        except fmpy.fmi1.FMICallException:
            out.append(None)
        if k == 15:
            saved, t_saved = f.getFMUstate(), t
        if k == 30:
            blob, t_blob = f.serializeFMUstate(f.getFMUstate()), t
        try:
            f.doStep(t if k != 20 else t + 1.0, h)  # k = 20: a wrong time, refused
            t += h
            out.append(tuple(x.hex() for x in f.getReal(outs)))
        except fmpy.fmi1.FMICallException:
            out.append(None)
        if k == 45:  # back to the state saved at k = 15
            f.setFMUstate(saved)
            t = t_saved
        if k == 60:  # and to the state serialized at k = 30
            f.setFMUstate(f.deSerializeFMUstate(blob))
            t = t_blob
    f.terminate()
    f.freeInstance()
    return out


def _api_sequence(load_speed_input: bool) -> list:
    """The same sequence with the Python API's fast engine (`FastEngine.advance`)."""
    from gearpair import Effects, GearParams
    from gearpair.fast import FastEngine

    eng = FastEngine(GearParams(), Effects(), rtol=1e-8)

    def record(summary=None):
        o = eng.outputs()
        values = {n: getattr(o, n, None) for n in STEP_OUTPUTS}
        if summary is None:
            from gearpair.engine import StepSummary

            summary = StepSummary.at_instant(o)
        values.update((n, getattr(summary, n)) for n in STEP_OUTPUTS if values[n] is None)
        return tuple(float(values[n]).hex() for n in STEP_OUTPUTS)

    eng.reset(t0=0.0, torque=3900.0, speed=100 * RPM, static=True)
    out = [record()]
    t, torque, speed = 0.0, 3900.0, 100 * RPM
    for k, (h, tq, w) in enumerate(SCHEDULE):
        if k == 10:  # the whole set refused: the old inputs kept
            out.append(None)
        else:
            torque, speed = tq, w
        if k == 15:
            saved, t_saved = eng.snapshot(), t
        if k == 30:
            blob, t_blob = eng.get_state(), t
        if k == 20:
            out.append(None)
        else:
            load = (speed / 1.5,) if load_speed_input else ()
            out.append(record(eng.advance(t + h, torque, speed, *load)))
            t += h
        if k == 45:
            eng.restore(saved)
            t = t_saved
        if k == 60:
            eng.set_state(blob)
            t = t_blob
    return out


STEP_OUTPUTS = ("dte", "mesh_force", "friction_force", "output_torque", "input_torque_reaction",
                "input_torque", "gear1_speed", "gear2_speed", "sliding_velocity",
                "stick_fraction", "separation_fraction", "mesh_force_max", "back_fraction",
                "mesh_force_mean", "mesh_force_min")


@pytest.mark.parametrize("load_speed_input", [False, True])
def test_the_fmu_step_is_bit_identical_to_the_python_api(fmu_path, md, tmp_path,
                                                         load_speed_input):
    unzip = fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "fmu"))
    fmu = _fmu_sequence(md, unzip, load_speed_input)
    api = _api_sequence(load_speed_input)
    assert len(fmu) == len(api)
    for k, (a, b) in enumerate(zip(fmu, api, strict=True)):
        assert a == b, (k, a, b)
    steps = [r for r in fmu if r is not None]
    assert len(steps) == 1 + 79  # the initial outputs, all steps but the one at a wrong time
    stick = [float.fromhex(r[STEP_OUTPUTS.index("stick_fraction")]) for r in steps]
    assert max(stick) > 0.1  # the compared steps include stick-slip switches


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


def test_a_state_restored_into_another_instance_goes_on_alike(fmu_path, md, tmp_path):
    """A serialized state set into a second instance: it goes on with the first one's
    outputs, step for step."""
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
    for k in range(5, 25):
        for g in (a, b):
            g.fmu.doStep(k * 1e-4, 1e-4)
        assert a.fmu.getReal(outs) == b.fmu.getReal(outs)
    for g in (a, b):
        g.fmu.terminate()
        g.fmu.freeInstance()
