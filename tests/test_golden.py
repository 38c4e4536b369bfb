"""The fast engine reproduces its golden trajectories bit for bit (tests/golden/make_golden.py).

The golden file holds, for every shipped scene, every hard case and every effect combination,
the outputs and step figures of each communication step and the final engine state, as the
engine computed them before its split into a package. Every value must be reproduced exactly
(``np.array_equal``, NaN equal to NaN): a refactoring that changes one bit of one trajectory
fails here. A change of the trajectories that is intended regenerates the file with the
command in make_golden.py's docstring, and its commit says why.

Bit for bit holds on every x86-64 machine, whatever its BLAS kernel and C library paths: the
model's set-up and the engine call no BLAS, LAPACK or C-library elementary function
(`gearpair.fast.detmath`, `detlinalg`, `setupmath`); tests/test_same_bits.py runs cases under
other kernels, math paths and CPU targets.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

sys.path.insert(0, str(Path(__file__).resolve().parent / "golden"))
import make_golden  # noqa: E402

CASES = {c.name: c for c in make_golden.all_cases()}


@pytest.fixture(scope="module")
def golden():
    with np.load(make_golden.GOLDEN) as f:
        return {k: f[k] for k in f.files}


def test_every_case_has_golden_values(golden):
    stored = {k.rsplit("/", 1)[0] for k in golden}
    assert stored == set(CASES), sorted(stored ^ set(CASES))


@pytest.mark.parametrize("name", sorted(CASES))
def test_golden(name, golden):
    from dataclasses import replace

    case = replace(CASES[name], steps=golden[f"{name}/steps"])
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
