"""Natural frequencies and mode shapes (`gearpair.modal`, `gearpair modes`): the modal API,
and the modes of the model a scene actually simulates (slip and stick models, torsional)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gearpair import GearParams
from gearpair.cli import main
from gearpair.modal import kr2_for_first_mode, natural_frequencies

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "examples" / "scenes"


def test_modal_api_takes_gearparams():
    f = natural_frequencies(GearParams())
    assert f[0] == pytest.approx(32.0, abs=1e-3)  # Table 1 with its kr2: the paper's mode
    assert len(natural_frequencies(GearParams(), "stick")) == 5
    assert kr2_for_first_mode(GearParams(), 32.0) == pytest.approx(GearParams().kr2, rel=1e-4)


def test_cli_modes_of_a_scene(capsys):
    assert main(["modes", str(ROOT / "examples/scenes/nvh_torsional.toml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["slip"]["frequencies_hz"]) == 2  # the scene's torsional model


def test_modes_of_a_torsional_friction_off_scene_are_the_slip_model_in_u1_u2(capsys):
    assert main(["modes", str(SCENES / "nvh_torsional.toml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"]["models"] == ["slip"] and out["model"]["friction"] == "off"
    assert out["stick"] is None  # friction off: the teeth never stick
    slip = out["slip"]
    assert slip["coordinates"] == ["u1", "u2"]
    assert len(slip["frequencies_hz"]) == 2 and all(len(s) == 2 for s in slip["mode_shapes"])
    assert main(["modes", str(SCENES / "nvh_torsional.toml")]) == 0
    text = capsys.readouterr().out
    assert "torsional (u1, u2; rigid supports), friction off: the slip model only" in text
    assert "stick model" not in text and "x1" not in text


def test_modes_of_a_stick_slip_scene_keep_both_models(capsys):
    assert main(["modes", str(SCENES / "paper_stick_slip.toml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"]["models"] == ["slip", "stick"]
    assert len(out["slip"]["frequencies_hz"]) == 6 and len(out["stick"]["frequencies_hz"]) == 5


def test_torsional_stick_model_has_one_mode_in_u1_u2(capsys):
    """Rigid supports leave u1 and u2; a stuck pair ties them: one mode, no x or y."""
    assert main(["modes", "--dof", "torsional", "--sliding", "full", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"]["friction"] == "stick_slip"
    assert out["stick"]["coordinates"] == ["u1", "u2"]
    assert len(out["stick"]["frequencies_hz"]) == 1
    assert main(["modes", str(SCENES / "nvh_torsional.toml"), "--friction", "off"]) == 2
    assert "--friction: set these in the scene file" in capsys.readouterr().err
