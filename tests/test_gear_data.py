"""Own gear data: bodies and kr2 derived from the geometry (API, scenes, command line), the
warning when Table 1's bodies meet other geometry, `--set` and its errors, and the warning
for a torque the teeth cannot carry (ISO nominal tooth-root load)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from gearpair import GearParams
from gearpair.cli import main
from gearpair.geometry import GearDataWarning, body_mass_inertia, steel_body
from gearpair.modal import derive_params, natural_frequencies, tune_kr2
from gearpair.scenes import SceneError, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]
# A user's gear: module 4 mm, 25/60 teeth, 40 mm face width, mean mesh stiffness 8e8 N/m
USER = dict(module=4e-3, z1=25, z2=60, face_width=0.04, km_mean=8e8)
USER_SET = [a for k, v in USER.items() for a in ("--set", f"{k}={v}")]
# the same with bodies as solid steel discs and kr2 tuned for a 32 Hz first mode
USER_DERIVED_SET = USER_SET + ["--bore-ratio", "0", "--first-mode-hz", "32"]


# -- bodies and kr2 from the geometry ------------------------------------------------------
def test_steel_rings_reproduce_table1_bodies():
    """Table 1's masses and inertias are steel rings of bore ratio 0.8 (within 0.7 %)."""
    p = steel_body(GearParams(), 0.8)
    d = GearParams()
    for k in ("m1", "J1", "m2", "J2"):
        assert getattr(p, k) == pytest.approx(getattr(d, k), rel=7e-3), k
    m, j = body_mass_inertia(0.004, 25, 0.04, 0.0)  # a solid disc: m r^2 / 2
    r = 0.004 * 25 / 2
    assert m == pytest.approx(7850 * np.pi * r**2 * 0.04)
    assert j == pytest.approx(0.5 * m * r**2)
    with pytest.raises(ValueError, match="bore_ratio"):
        body_mass_inertia(0.004, 25, 0.04, 1.0)


def test_user_gear_warns_and_derivation_tunes_the_first_mode():
    user = GearParams(**USER)
    with pytest.warns(GearDataWarning, match="m1, J1, m2, J2 are Table 1's values"):
        natural_frequencies(user)
    solid = steel_body(user, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GearDataWarning)  # derived bodies: no warning
        f_table1_kr2 = natural_frequencies(solid)[0]
        tuned = tune_kr2(solid, 32.0)
        assert natural_frequencies(tuned)[0] == pytest.approx(32.0, rel=1e-6)
    assert f_table1_kr2 == pytest.approx(109.4, abs=0.1)  # Table 1's kr2 on this gear
    assert tuned.kr2 < 0.1 * GearParams().kr2
    both = derive_params(user, bore_ratio=0.0, first_mode_hz=32.0)
    assert both == tuned
    with pytest.raises(ValueError, match="out of reach"):
        tune_kr2(solid, 5000.0)


def test_scene_derives_bodies_and_kr2(tmp_path):
    gear = "\n".join(f"{k} = {v}" for k, v in USER.items())
    scene = tmp_path / "own.toml"
    scene.write_text(f"[gear]\n{gear}\nbore_ratio = 0\nfirst_mode_hz = 32\n")
    p = load_scene(scene).params
    assert p.m1 == pytest.approx(body_mass_inertia(0.004, 25, 0.04, 0.0)[0])
    assert natural_frequencies(p)[0] == pytest.approx(32.0, rel=1e-6)
    with pytest.raises(SceneError, match=r"\[gear\] give m1 or bore_ratio"):
        parse_scene({"gear": {"m1": 3.0, "bore_ratio": 0.5}})
    with pytest.raises(SceneError, match=r"\[gear\] give kr2 or first_mode_hz"):
        parse_scene({"gear": {"kr2": 1e6, "first_mode_hz": 30}})
    with pytest.raises(SceneError, match=r"bore_ratio = 1.5 is out of range"):
        parse_scene({"gear": {"bore_ratio": 1.5}})


def test_cli_modes_with_own_gear_data(capsys):
    rc = main(["modes", "--json", *USER_SET, "--bore-ratio", "0", "--first-mode-hz", "32",
               "--mu", "0.03"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["slip"]["frequencies_hz"][0] == pytest.approx(32.0, abs=1e-5)
    assert out["params"]["z1"] == 25 and out["params"]["mu"] == 0.03
    assert out["params"]["m1"] == pytest.approx(body_mass_inertia(0.004, 25, 0.04, 0.0)[0])
    # Table 1's bodies with the user geometry: the run goes on, with one warning line
    assert main(["modes", *USER_SET]) == 0
    err = capsys.readouterr().err
    assert err.startswith("gearpair: warning: m1, J1, m2, J2 are Table 1's values")
    assert err.count("\n") == 1


@pytest.mark.parametrize("argv, msg", [
    (["simulate", "--set", "modul=0.004"], "--set modul: no such gear parameter (did you "
                                             "mean module?)"),
    (["simulate", "--set", "module"], "--set 'module': use NAME=VALUE"),
    (["simulate", "--set", "z1=abc"], "--set 'z1=abc': 'abc' is not a number"),
    (["simulate", "--set", "z1=25.5"], "z1 must be a whole number"),
    (["simulate", "--set", "module=0.5"], "module = 0.5 is out of range; allowed (0, 0.1] m"),
    (["simulate", "--set", "kr2=1e6", "--first-mode-hz", "30"], "do not also --set kr2"),
    (["simulate", "--mu", "0.1", "--set", "mu=0.2"], "give --mu or --set mu=..., not both"),
    (["modes", "--set", "mu=2"], "mu = 2.0 is out of range; allowed [0, 1]"),
    (["modes", "--bore-ratio", "1"], "bore_ratio = 1.0 is out of range"),
])
def test_cli_gear_data_errors_are_one_line_exit_2(argv, msg, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1 and err.startswith("gearpair: error: ")


def test_cli_simulate_with_own_gear_data(capsys):
    rc = main(["simulate", "--engine", "fast", "--json", "--t-end", "0.004", "--dt", "1e-4",
               "--torque", "300", "--friction", "nominal", *USER_SET, "--bore-ratio", "0",
               "--first-mode-hz", "32"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["gear_changed"]["z1"] == 25 and out["gear_changed"]["kr2"] < 4e5
    rb1 = GearParams(**USER).rb1
    assert 0.7 * 300 / rb1 < out["mesh_force_n"]["mean"] < 1.3 * 300 / rb1


def test_cli_set_applies_over_a_scene(capsys):
    scene = str(ROOT / "examples/scenes/paper_slip.toml")
    rc = main(["simulate", scene, "--t-end", "0.002", "--json", "--set", "mu=0.05"])
    assert rc == 0
    assert json.loads(capsys.readouterr().out)["gear_changed"] == {"mu": 0.05}


# -- a torque the teeth cannot carry -------------------------------------------------------
def test_unit_load_is_the_iso_nominal_tooth_root_load():
    from gearpair import GearParams
    from gearpair.geometry import UNIT_LOAD_LIMIT, load_implausibility, unit_load

    # Ft = 2 T / d1 = 2 * 3900 / (0.004 * 25) = 78 kN over b m = 40 mm * 4 mm
    assert unit_load(GearParams(**USER), 3900.0) == pytest.approx(487.5)
    assert unit_load(GearParams(), -3900.0) == pytest.approx(7800 / 0.198 / 1200)  # 33 N/mm2
    assert load_implausibility(GearParams(), 3900.0) is None
    msg = load_implausibility(GearParams(**USER), 3900.0)
    assert "Ft/(b m) = 487 N/mm2" in msg and f"exceeds {UNIT_LOAD_LIMIT:g} N/mm2" in msg
    # the bound: just below and above 250 N/mm2 for Table 1's gears
    t_limit = UNIT_LOAD_LIMIT * 1e6 * 0.2 * 0.006 * 0.006 * 33 / 2
    assert load_implausibility(GearParams(), 0.999 * t_limit) is None
    assert load_implausibility(GearParams(), 1.001 * t_limit) is not None


def test_simulate_and_scenes_warn_of_an_implausible_torque(tmp_path):
    from gearpair import GearParams
    from gearpair.geometry import GearDataWarning, steel_body
    from gearpair.results import simulate
    from gearpair.scenes import load_scene

    own = steel_body(GearParams(**USER), 0.0)
    with pytest.warns(GearDataWarning, match=r"Ft/\(b m\) = 487 N/mm2"):
        simulate(own, t_end=2e-4, torque=3900.0, engine="reference")
    with pytest.warns(GearDataWarning, match=r"Ft/\(b m\) = 487 N/mm2"):  # a ramp's peak
        simulate(own, t_end=2e-4, torque=lambda t: 270.0 + 3630.0 * t / 2e-4, dt=1e-4,
                 engine="reference")
    gear = "\n".join(f"{k} = {v}" for k, v in USER.items())
    scene = tmp_path / "own.toml"
    scene.write_text(f"t_end = 2e-4\n[gear]\n{gear}\nbore_ratio = 0\n"
                     "[inputs]\ntorque = {kind = \"ramp\", from = 270.0, to = 3900.0, "
                     "t0 = 0, t1 = 1e-4}\n")
    with pytest.warns(GearDataWarning, match="torque 3900 N.m is implausible"):
        load_scene(scene).run("reference")


def test_cli_warns_of_an_implausible_torque_on_stderr_and_runs(capsys):
    assert main(["simulate", *USER_DERIVED_SET, "--t-end", "0.002", "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["torque_nm"] == 3900.0  # it ran
    lines = [ln for ln in cap.err.splitlines() if "implausible" in ln]
    assert len(lines) == 1 and lines[0].startswith("gearpair: warning: torque 3900 N.m")
    assert main(["simulate", *USER_DERIVED_SET, "--t-end", "0.002", "--torque", "270"]) == 0
    assert "implausible" not in capsys.readouterr().err


def test_sweep_warns_of_its_heaviest_point_before_the_run(no_runs, tmp_path, capsys):
    with pytest.raises(AssertionError, match="run started"):
        main(["sweep", "torque", "270,3900,1000", "--scheduler", "serial", *USER_SET,
              "--out", str(tmp_path / "t")])
    err = capsys.readouterr().err
    assert err.count("implausible") == 1 and "torque 3900 N.m" in err
