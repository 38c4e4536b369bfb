"""The package and the command line as a new user meets them (issue 17, items 5-8): own gear
data, help texts and ranges, the docs, CSV files that go back in, figure titles."""

from __future__ import annotations

import argparse
import json
import re
import warnings
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from gearpair import GearParams
from gearpair.cli import build_parser, main, plot_title
from gearpair.geometry import GearDataWarning, body_mass_inertia, steel_body
from gearpair.modal import derive_params, kr2_for_first_mode, natural_frequencies, tune_kr2
from gearpair.params import RTOL_MAX, RTOL_MIN
from gearpair.scenes import SceneError, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]
# The user gear: module 4 mm, 25/60 teeth, 40 mm face width, mean mesh stiffness 8e8
USER = dict(module=4e-3, z1=25, z2=60, face_width=0.04, km_mean=8e8)
USER_SET = [a for k, v in USER.items() for a in ("--set", f"{k}={v}")]


# -- 5. own gear data ----------------------------------------------------------------------------
def test_modal_api_takes_gearparams():
    f = natural_frequencies(GearParams())
    assert f[0] == pytest.approx(32.0, abs=1e-3)  # Table 1 with its kr2: the paper's mode
    assert len(natural_frequencies(GearParams(), "stick")) == 5
    assert kr2_for_first_mode(GearParams(), 32.0) == pytest.approx(GearParams().kr2, rel=1e-4)


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
    assert f_table1_kr2 == pytest.approx(109.4, abs=0.1)  # the 109.5 Hz
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


def test_cli_modes_of_a_scene(capsys):
    assert main(["modes", str(ROOT / "examples/scenes/nvh_torsional.toml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["slip"]["frequencies_hz"]) == 2  # the scene's torsional model


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


# -- 6. help, version, ranges, units -------------------------------------------------------------
def _subparsers(ap: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    act = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    return dict(act.choices)


def test_every_option_of_every_command_has_help_with_choices_and_default():
    subs = _subparsers(build_parser())
    assert set(subs) == {"modes", "simulate", "sweep", "bench"}
    for name, sp in subs.items():
        for act in sp._actions:
            if isinstance(act, argparse._HelpAction):
                continue
            where = f"gearpair {name} {'/'.join(act.option_strings) or act.dest}"
            assert act.help and len(act.help) > 10, where
            if act.option_strings and act.type in (float, int) and name != "bench":
                assert "default" in act.help, where  # every number says its default
            if act.option_strings and act.choices is None and act.type is None \
                    and act.nargs == 0:
                continue  # a flag
    sim = subs["simulate"].format_help()
    for text in ("{off,nominal,regularized,stick_slip}", "(N.m)", "(r/min)", "default 3900",
                 "[1e-12, 0.001]"):
        assert text in sim, text
    sweep = subs["sweep"].format_help()
    assert "{stick_slip" not in sweep and "{off,nominal,regularized,stick_slip}" in sweep
    assert "default 1e-07" in sweep


def test_version_and_bare_command(capsys):
    from gearpair import __version__

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"gearpair {__version__}"
    assert main([]) == 2
    out = capsys.readouterr().out
    assert out.startswith("usage: gearpair") and "simulate" in out and "modes" in out


def test_one_rtol_range_everywhere(capsys):
    import importlib.util

    from gearpair.fast import FastEngine
    from gearpair.reference import ReferenceEngine

    assert (RTOL_MIN, RTOL_MAX) == (1e-12, 1e-3)
    for engine in (FastEngine, ReferenceEngine):
        for bad in (1e-13, 1e-2):
            with pytest.raises(ValueError, match=r"rtol = .* allowed \[1e-12, 0.001\]$"):
                engine(rtol=bad)
    with pytest.raises(SceneError, match=r"rtol = 0.01 is out of range; allowed "
                                         r"\[1e-12, 0.001\]$"):
        parse_scene({"solver": {"rtol": 1e-2}})
    assert main(["simulate", "--rtol", "1e-13", "--t-end", "0.001"]) == 2
    assert "allowed [1e-12, 0.001]" in capsys.readouterr().err
    spec = importlib.util.spec_from_file_location("_gp_slave", ROOT / "fmu_src" / "GearPair.py")
    pytest.importorskip("pythonfmu")
    slave = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(slave)
    rtol = next(v for v in slave.interface() if v["name"] == "rtol")
    assert (rtol["min"], rtol["max"]) == (RTOL_MIN, RTOL_MAX)


def test_dimensionless_units_are_not_printed_as_1():
    with pytest.raises(ValueError) as exc:
        GearParams(mu=2.0)
    assert str(exc.value) == "mu = 2.0 is out of range; allowed [0, 1]"
    with pytest.raises(ValueError) as exc:
        GearParams(m1=-1.0)
    assert str(exc.value).endswith("allowed (0, 100000] kg")


# -- 7. docs -------------------------------------------------------------------------------------
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _code_blocks(text: str) -> list[str]:
    return re.findall(r"```(?:bash|sh|console)?\n(.*?)```", text, flags=re.S)


def test_docs_run_commands_from_the_venv():
    """After the README's setup only .venv/bin has gearpair, fmpy, dask, pytest on it."""
    for path in DOCS:
        for block in _code_blocks(path.read_text()):
            for line in block.splitlines():
                cmd = line.strip()
                first = cmd.split(" ", 1)[0] if cmd else ""
                assert first not in ("gearpair", "fmpy", "python", "pytest", "dask", "ruff"), \
                    f"{path.name}: {cmd}"


def test_model_reconstruction_is_in_the_repository():
    readme = (ROOT / "README.md").read_text()
    assert "../shared" not in readme and "docs/model.md" in readme
    for path in DOCS:
        assert "MODEL.md" not in path.read_text(), path.name  # the private notes' name
    model = (ROOT / "docs" / "model.md").read_text()
    for eq in ("(1)", "(3)", "(8)", "(9)", "(12)", "(14)", "(26)", "(27)"):
        assert f"Eq. {eq}" in model or f"Eqs. {eq}" in model or eq in model, eq
    for topic in ("coordinates", "mesh stiffness", "backlash", "friction", "stick",
                  "sliding velocity", "stick ratio", "contact-loss ratio", "Own gear data"):
        assert topic.lower() in model.lower(), topic


def test_sweep_doc_snippet_guards_its_entry_point():
    doc = (ROOT / "docs" / "sweep.md").read_text()
    snippet = re.search(r"```python\n(.*?)```", doc, flags=re.S).group(1)
    assert 'if __name__ == "__main__":' in snippet
    compile(snippet, "sweep.md", "exec")


# -- 8. CSV files and figures --------------------------------------------------------------------
def test_csv_written_by_gearpair_goes_back_in(tmp_path, capsys):
    out = tmp_path / "run.csv"
    assert main(["simulate", "--engine", "fast", "--t-end", "0.003", "--speed-rpm", "150",
                 "--torque", "3000", "--out", str(out)]) == 0
    capsys.readouterr()
    header = out.read_text().splitlines()[0].split(",")
    assert header[0] == "time" and all(re.fullmatch(r"[a-z0-9_]+", h) for h in header)
    for name in ("torque", "speed", "load_speed"):  # every input of the FMU
        assert name in header
    # a scene reads its torque and speed back, without a word about the output columns
    # (they are gearpair's own output names, not misspelt inputs)
    scene = tmp_path / "again.toml"
    scene.write_text(f'[inputs.csv]\nfile = "{out.name}"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sc = load_scene(scene)
    assert capsys.readouterr().err == ""
    assert sc.inputs.torque(0.001) == pytest.approx(3000.0)
    assert sc.inputs.speed(0.001) == pytest.approx(150 * 2 * np.pi / 60)
    # fmpy reads the same names (its reader keeps them as they are)
    fmpy_util = pytest.importorskip("fmpy.util")
    sig = fmpy_util.read_csv(str(out))
    assert {"time", "torque", "speed", "load_speed"} <= set(sig.dtype.names)
    assert sig["load_speed"][1] == pytest.approx(sig["speed"][1] * 33 / 80)


def test_readme_csv_example_gives_every_fmu_input():
    readme = (ROOT / "README.md").read_text()
    header = re.search(r"printf '([a-z_,]+)\\n", readme).group(1).split(",")
    pytest.importorskip("pythonfmu")
    import importlib.util

    spec = importlib.util.spec_from_file_location("_gp_slave2", ROOT / "fmu_src" / "GearPair.py")
    slave = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(slave)
    inputs = [v["name"] for v in slave.interface() if v["causality"] == "input"]
    assert header[0] == "time" and set(inputs) <= set(header[1:])


def test_plot_title_gives_the_operating_point():
    sc = load_scene(ROOT / "examples/scenes/paper_stick_slip.toml")
    title = plot_title(sc, "fast")
    for text in ("paper_stick_slip", "100 r/min", "3900 N.m", f"mu {sc.params.mu:g}",
                 "friction stick_slip", "fast engine"):
        assert text in title, text
    ramp = load_scene(ROOT / "examples/scenes/torque_reversal_backlash.toml")
    title = plot_title(ramp, "reference")
    assert "3900->-3900 N.m ramp" in title and "backlash 100 um" in title
    assert [f.name for f in fields(GearParams)]  # (keeps the import honest)


def test_sweep_title_gives_the_operating_point():
    from gearpair.sweep import SweepSettings, sweep_title

    title = sweep_title("speed_rpm", SweepSettings(torque=3000.0, params=(("mu", 0.03),),
                                                   friction="nominal"))
    assert "sweep of speed_rpm" in title and "3000 N.m" in title and "mu 0.03" in title
    assert "friction nominal" in title and "r/min" not in title  # the swept one is the axis
    assert "100 r/min" in sweep_title("torque", SweepSettings())


def test_readme_says_what_is_tested_where():
    import zipfile

    readme = (ROOT / "README.md").read_text()
    assert "Tested on Linux x86_64" in readme
    fmu = ROOT / "dist" / "GearPair.fmu"
    if fmu.is_file():  # every platform the FMU ships a binary for is named with its status
        with zipfile.ZipFile(fmu) as z:
            platforms = {n.split("/")[1] for n in z.namelist()
                         if n.startswith("binaries/") and n.count("/") >= 2}
        for plat in platforms:
            assert plat in readme, plat
