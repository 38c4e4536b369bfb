"""The plain scipy implementation (`gearpair.bench.plain_scipy`) against the fast engine.

It is the bench's "what a user would write" row, so its numbers are only worth quoting if it
integrates the same model: it must agree with the fast engine to its tolerance, through the
pair entries/exits and the sticks of the first 20 ms at the paper's point. And it must stay
what a user writes: it takes data from the package, never its engines.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gearpair.bench import plain_scipy
from gearpair.effects import Effects, StiffnessSpec
from gearpair.results import simulate

ROOT = Path(__file__).resolve().parents[1]
# what it may import of gearpair: data (gear data, geometry, the stiffness law); the fast
# engine only in `compare_with_fast`, the comparison
DATA = {"gearpair.effects", "gearpair.geometry", "gearpair.params", "gearpair.stiffness"}


@pytest.fixture(scope="module")
def plain():
    return plain_scipy


def _gearpair_imports(node: ast.AST) -> set[str]:
    out = {n.module for n in ast.walk(node) if isinstance(n, ast.ImportFrom)}
    out |= {a.name for n in ast.walk(node) if isinstance(n, ast.Import) for a in n.names}
    return {m for m in out if m and m.startswith("gearpair")}


def test_takes_only_data_from_the_package():
    tree = ast.parse(Path(plain_scipy.__file__).read_text())
    compare = next(n for n in tree.body
                   if isinstance(n, ast.FunctionDef) and n.name == "compare_with_fast")
    rest = set().union(*(_gearpair_imports(n) for n in tree.body if n is not compare))
    assert rest <= DATA, rest - DATA
    assert _gearpair_imports(compare) <= DATA | {"gearpair.results"}


def test_the_repository_entry_point_runs_it():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "plain_scipy.py"),
                          "--help"], capture_output=True, text=True, timeout=120, check=True)
    assert "--method" in out.stdout


def _fast(friction: str, t_end: float, dt: float = 1e-4,
          stiffness: str = "potential_energy") -> dict:
    fx = Effects(friction=friction, stiffness=StiffnessSpec(stiffness))
    traj = simulate(engine="fast", effects=fx, t_end=t_end, dt=dt, rtol=1e-12)
    return {k: np.asarray(traj[k], dtype=float) for k in ("dte", "mesh_force")}


@pytest.mark.parametrize("friction", ["off", "nominal", "stick_slip"])
def test_agrees_with_the_fast_engine(plain, friction):
    # 20 ms: one pair exit (13.6 ms), one entry (18.2 ms), for stick-slip the first stick
    t_end = 0.02
    ref = _fast(friction, t_end)
    model = plain.PlainGearPair(friction, rtol=1e-10)
    got = model.simulate(t_end, 1e-4)
    for name in ("dte", "mesh_force"):
        assert np.all(np.isfinite(got[name]))
        err = np.max(np.abs(got[name] - ref[name])) / np.max(np.abs(ref[name]))
        assert err < 1e-8, (name, err)
    if friction == "stick_slip":
        # entering the stick at 14.9 ms, leaving it, entering the next at 17.4 ms
        assert model.n_events >= 3
    else:
        assert model.n_events == 0


def test_switches_between_two_output_points(plain):
    # recorded every 1 ms, the first stick (14.86-15.00 ms) starts and ends between two
    # points: solve_ivp calls that return no output point at all
    ref = _fast("stick_slip", 0.02, dt=1e-3)
    model = plain.PlainGearPair("stick_slip", rtol=1e-10)
    got = model.simulate(0.02, 1e-3)
    assert model.n_events >= 3
    err = np.max(np.abs(got["dte"] - ref["dte"])) / np.max(np.abs(ref["dte"]))
    assert err < 1e-8, err


def test_error_follows_the_tolerance(plain):
    ref = _fast("stick_slip", 0.02)
    errs = []
    for rtol in (1e-5, 1e-8):
        got = plain.PlainGearPair("stick_slip", rtol=rtol).simulate(0.02, 1e-4)
        errs.append(np.max(np.abs(got["dte"] - ref["dte"])) / np.max(np.abs(ref["dte"])))
    assert errs[1] < 0.01 * errs[0] and errs[1] < 1e-6, errs


@pytest.mark.parametrize("friction", ["off", "stick_slip"])
def test_rectangular_stiffness_agrees_with_the_fast_engine(plain, friction):
    # the rectangular law (issue 37 item 2): the total stiffness steps at the pair exit
    # (13.6 ms) and entry (18.2 ms); for stick-slip the first stick lies between them
    ref = _fast(friction, 0.02, stiffness="rectangular")
    model = plain.PlainGearPair(friction, rtol=1e-10, stiffness="rectangular")
    got = model.simulate(0.02, 1e-4)
    for name in ("dte", "mesh_force"):
        err = np.max(np.abs(got[name] - ref[name])) / np.max(np.abs(ref[name]))
        assert err < 1e-8, (name, err)
    assert (model.n_events >= 3) == (friction == "stick_slip")


def test_the_stiffness_law_is_the_packages(plain):
    # at the start of the run (static equilibrium) the plain model's stiffness is the law the
    # package builds: per pair the same constant (rectangular), or the potential-energy
    # spline, which is not constant along the path
    from gearpair.geometry import Geometry
    from gearpair.params import GearParams
    from gearpair.stiffness import MeshStiffness

    p = GearParams()
    g = Geometry.from_params(p)
    xi = np.linspace(0.0, g.path_length, 7)
    for kind in ("rectangular", "potential_energy"):
        model = plain.PlainGearPair("off", stiffness=kind)
        want = MeshStiffness.build(p, g, StiffnessSpec(kind)).pairs(xi, 2)
        assert np.allclose(model.stiffness(xi), want, rtol=1e-13, atol=0.0), kind
        assert np.allclose([model.k_at(x) for x in xi], want, rtol=1e-13, atol=0.0), kind
    assert np.ptp(want) > 0.1 * np.max(want)


def test_the_command_line_picks_law_and_friction(plain, capsys):
    assert plain.main(["--t-end", "0.002", "--stiffness", "rectangular",
                       "--friction", "off"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 1 and lines[0].startswith("off") and "rectangular" in lines[0]


def test_a_release_from_stick_is_not_a_reversal(plain):
    # a pair released from stick starts sliding at v = 0 with d v/dt = 0: its event must
    # start above zero, or rounding makes it fall at once and the release repeats (at rtol
    # 1e-6 this stalled at 87.2 ms, issue 37)
    model = plain.PlainGearPair("stick_slip", rtol=1e-6)
    seg = model.segment(0.0, 0.01)
    y = np.zeros(12)
    y[6] = -model.sliding(0.0, y, seg, 0)
    assert model.sliding(0.0, y, seg, 0) == 0.0
    dirs = [1.0] * len(seg.pairs)
    assert all(e(0.0, y) > 0.0 for e in model.events(seg, "contact", dirs, -1)[1:2])
    got = model.simulate(0.1, 1e-4)
    assert np.all(np.isfinite(got["dte"])) and model.n_events >= 10


def test_bad_friction_law_is_refused(plain):
    with pytest.raises(ValueError, match="friction"):
        plain.PlainGearPair("sticky")


def test_bad_stiffness_law_is_refused(plain):
    with pytest.raises(ValueError, match="stiffness"):
        plain.PlainGearPair("off", stiffness="table")
