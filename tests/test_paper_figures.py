"""The paper's figures (examples/paper/) run on their short setting and write PNG files; the
numbers behind the comparison (docs/paper_comparison.md) that are cheap are checked here."""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from gearpair import GearParams, Geometry

pytest.importorskip("matplotlib")
PAPER = Path(__file__).resolve().parents[1] / "examples" / "paper"
sys.path.insert(0, str(PAPER))

import comparison  # noqa: E402
import parametric  # noqa: E402
import stiffness_modes  # noqa: E402
import time_response  # noqa: E402
from common import SLIP, STICK, response  # noqa: E402


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return struct.unpack(">II", head[16:24])


@pytest.mark.parametrize(
    "fn", [*stiffness_modes.FIGURES, *time_response.FIGURES, *parametric.FIGURES],
    ids=lambda f: f.__name__)
def test_figure_writes_a_png(fn, tmp_path):
    path = fn(tmp_path, True)
    assert path.parent == tmp_path and path.name.startswith(fn.__name__.split("_")[0])
    w, h = _png_size(path)
    assert w >= 600 and h >= 300
    assert path.stat().st_size > 15_000  # axes, curves and text, not an empty canvas


def test_modal_claims():
    m = comparison.modal_claims()["paper"]
    assert m["slip_hz"][0] == pytest.approx(32.0, abs=0.05)      # the 32 Hz 'rigid' mode
    assert m["slip_mode1_rotation_share"] > 0.99                  # pure rotation
    assert m["slip_mode3_gear1_translation_share"] > 0.999        # pure translation, gear 1
    assert m["slip_mode5_gear2_translation_share"] > 0.999        # pure translation, gear 2
    assert len(m["stick_hz"]) == 5
    assert m["stick_max_relative_x"] < 1e-12                      # x1 = x2 in every stick mode


def test_time_response_is_steady_and_periodic():
    slip, stick = response(SLIP, True), response(STICK, True)
    n = slip["steps_per_period"]
    # the slip model never sticks; the stick-slip model does near the pitch point
    assert not np.any(slip["contact_state"] == 2)
    stuck = stick["contact_state"] == 2
    assert stuck.any() and np.all(np.abs(stick["sliding_velocity"][stuck]) < 1e-6)
    # stuck only near the pitch point (within a quarter base pitch), where the vibration
    # velocity can cancel the nominal sliding velocity
    g = Geometry.from_params(GearParams())
    assert np.max(np.abs(stick["xi_near"][stuck] - g.xi_pitch)) < 0.25 * g.base_pitch
    # Fig. 14: the mesh orders; the DTE's mean deflection is near Tr / (rb1 km)
    o = time_response.dte_orders(True)
    assert o[SLIP][1.0] > 10 * o[SLIP][0.5]
    assert 5 < np.mean(slip["dte"]) * 1e6 < 15
    assert slip["time"].size == 8 * n


def test_figure_sweeps_are_cached(tmp_path):
    a = parametric.speed_sweep(STICK, tmp_path, quick=True)
    b = parametric.speed_sweep(STICK, tmp_path, quick=True)
    assert b.elapsed_s == pytest.approx(a.elapsed_s, abs=1e-3)  # read back, not rerun
    assert [r["stick_ratio"] for r in b.records] == pytest.approx(
        [r["stick_ratio"] for r in a.records], rel=1e-9)
    assert all(r["status"] == "ok" for r in a.records)
