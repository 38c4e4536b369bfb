"""The slave's per-step fast path (`GearPair._make_fast_step`, the get/set overrides) against
its general path: the same call sequence through two instances of the built FMU's slave
class, one with the fast path switched off, gives bit-identical values of every variable
after every call, refusals and state restores included."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
pytest.importorskip("numba")

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


def _values(s) -> tuple:
    reals = [vr for vr, v in s.vars.items() if type(v).__name__ == "Real"]
    ints = [vr for vr, v in s.vars.items() if type(v).__name__ == "Integer"]
    return tuple(x.hex() for x in map(float, s.get_real(reals))), tuple(s.get_integer(ints))


@pytest.mark.parametrize("load_speed_input", [False, True])
def test_fast_path_is_bit_identical_to_general_path(slave_class, load_speed_input):
    cls, resources = slave_class
    fast, general = (cls(instance_name=n, resources=resources) for n in ("fast", "general"))
    general._make_fast_step = lambda: None  # the general `_do_step` for every call
    calls = {"general": 0}
    do_step = fast._do_step

    def counted(t, h):
        calls["general"] += 1
        return do_step(t, h)

    fast._do_step = counted
    vr = {v.name: k for k, v in fast.vars.items()}
    vin = [vr["torque"], vr["speed"], vr["load_speed"]]
    results = {}
    for s in (fast, general):
        out = []
        s.setup_experiment(0.0, None, None)
        s.set_boolean([vr["load_speed_input"]], [load_speed_input])
        s.set_real(vin, [3900.0, 100 * RPM, 100 * RPM / 1.5])
        s.enter_initialization_mode()
        s.exit_initialization_mode()
        out.append(_values(s))
        t, saved = 0.0, None
        for k in range(80):
            h = (1e-4, 3e-4, 1e-3)[k % 3]
            u = [3900.0 + 40.0 * k, (100 + k) * RPM, (100 + k) * RPM / 1.5]
            if k == 10:
                u[0] = math.nan  # refused: discard, outputs kept
            if k == 12:
                u[1] = 3e4  # out of range
            s.set_real(vin, u)
            if k == 15:
                saved = s._get_fmu_state()
            ok = s.do_step(t if k != 20 else t + 1.0, h)  # k = 20: a wrong time, refused
            out.append((ok, _values(s)))
            if ok:
                t += h
            if k == 45:  # back to the state saved at k = 15
                s._set_fmu_state(saved)
                t = s._engine.time
                out.append(_values(s))
        results[s.instance_name] = out
    assert results["fast"] == results["general"]
    steps = [r for r in results["fast"][1:] if isinstance(r[0], bool)]
    assert sum(ok for ok, _ in steps) == 77
    names = [v.name for v in fast.vars.values() if type(v).__name__ == "Real"]
    stick = [float.fromhex(r[names.index("stick_fraction")]) for _, (r, _) in steps]
    assert max(stick) > 0.1  # the compared steps include stick-slip switches
    # the general path: the first step, the three refusals and the step after the restore
    assert calls["general"] <= 6, calls
    assert fast._fast_step is not None and general._fast_step is None


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
