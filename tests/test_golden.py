"""The fast engine reproduces its golden trajectories bit for bit (tests/golden/make_golden.py).

The golden file holds, for every shipped scene, every hard case and every effect combination,
the outputs and step figures of each communication step and the final engine state, as the
engine computed them before its split into a package. Every value must be reproduced exactly
(``np.array_equal``, NaN equal to NaN): a refactoring that changes one bit of one trajectory
fails here. A change of the trajectories that is intended regenerates the file with the
command in make_golden.py's docstring, and its commit says why.

Bit for bit holds in the environment the golden file was made in (``environment.json``:
OpenBLAS's kernel and glibc's math paths, `measure_spread.is_golden_environment`). Elsewhere
the model's setup (BLAS, LAPACK) and the engine's ``exp``, ``pow``, ``tanh`` (glibc) round
differently, and a case is compared at its own tolerance, 16 times the spread measured under
other environments (`measure_spread.py`) and at least 1e-11 of each column's magnitude; a
case whose spread exceeds 1e-6 takes another discrete branch there (a stick decision, a step
count) and is skipped with that reason. Each tolerance is reported in the test summary.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

sys.path.insert(0, str(Path(__file__).resolve().parent / "golden"))
import make_golden  # noqa: E402
import measure_spread  # noqa: E402

CASES = {c.name: c for c in make_golden.all_cases()}
ENV = json.loads(measure_spread.ENV_JSON.read_text())
BRANCHING = 1e-6  # a spread above this is another branch of a discrete decision


@pytest.fixture(scope="module")
def golden():
    with np.load(make_golden.GOLDEN) as f:
        return {k: f[k] for k in f.files}


def test_golden_environment_is_told_by_kernel_and_libm():
    made = ENV["made_in"]
    assert measure_spread.is_golden_environment(made, {"openblas": ["SkylakeX"] * 2,
                                                       "libm_fma": True})
    for env in ({"openblas": ["SkylakeX", "Haswell"], "libm_fma": True},
                {"openblas": ["SkylakeX"], "libm_fma": False}, {"openblas": [], "libm_fma": True}):
        assert not measure_spread.is_golden_environment(made, env), env


def test_scaled_deviation_scales_by_column_and_treats_nan():
    w = np.array([[1.0, 1e-6], [2.0, np.nan]])
    assert measure_spread.scaled_deviation(w.copy(), w) == 0.0
    v = w + [[0.0, 1e-12], [0.0, 0.0]]
    assert measure_spread.scaled_deviation(v, w) == pytest.approx(1e-6)
    assert measure_spread.scaled_deviation(np.nan_to_num(w), w) == np.inf


def test_every_case_has_golden_values(golden):
    stored = {k.rsplit("/", 1)[0] for k in golden}
    assert stored == set(CASES), sorted(stored ^ set(CASES))


@pytest.mark.parametrize("name", sorted(CASES))
def test_golden(name, golden, record_property):
    from dataclasses import replace

    case = replace(CASES[name], steps=golden[f"{name}/steps"])
    env = measure_spread.environment()
    if not measure_spread.is_golden_environment(ENV["made_in"], env):
        spread = ENV["spread"][name]
        where = (f"OpenBLAS {'/'.join(sorted(set(env['openblas'])))}, libm FMA "
                 f"{'on' if env['libm_fma'] else 'off'}; golden file: OpenBLAS "
                 f"{'/'.join(ENV['made_in']['openblas'])}, libm FMA on")
        if spread > BRANCHING:
            record_property("golden_env", where)
            record_property("golden", f"{name}: skipped, spread {spread:.2g}")
            pytest.skip(f"{name}: takes another branch outside the golden file's "
                        f"environment (spread {spread:.2g}; {where})")
        tol = max(16.0 * spread, 1e-11)
        got = make_golden.run_case(case)
        worst = max(measure_spread.scaled_deviation(got[k], golden[f"{name}/{k}"])
                    for k in got)
        record_property("golden_env", where)
        record_property("golden", f"{name}: {worst:.2g} (tolerance {tol:.2g})")
        assert worst <= tol, (f"{name}: deviates {worst:.3g} of a column's magnitude, "
                              f"tolerance {tol:.3g} ({where})")
        return
    got = make_golden.run_case(case)
    for k, v in got.items():
        want = golden[f"{name}/{k}"]
        assert v.shape == want.shape, (k, v.shape, want.shape)
        same = np.array_equal(v, want, equal_nan=True)
        if not same:
            bad = np.argwhere(~((v == want) | (np.isnan(v) & np.isnan(want))))
            i = tuple(bad[0])
            rel = abs(v[i] - want[i]) / max(abs(want[i]), 1e-300)
            pytest.fail(f"{name}/{k}{list(i)}: {v[i]!r} != golden {want[i]!r} "
                        f"(relative {rel:.3g}; {len(bad)} values differ)")
