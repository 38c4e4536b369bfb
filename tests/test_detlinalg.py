"""gearpair.fast.detlinalg: small linear algebra with a fixed operation order, checked against
numpy/scipy (and mpmath where scipy's own error is the larger), by its defining properties,
and for the same bits in another process: another OpenBLAS core (which changes numpy's and
scipy's last bits, not ours), code compiled for a plain x86-64 CPU (SSE2, no FMA) instead of
this one, the Python reading of the same source (NUMBA_DISABLE_JIT: each operation rounded
as written) and the digest recorded when the kernels were written (`RECORDED_DIGEST`).
"""

from __future__ import annotations

import hashlib
import os
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.interpolate import CubicSpline

from gearpair import GearParams, modal
from gearpair.effects import Effects
from gearpair.fast import detlinalg as dl

EPS = np.finfo(float).eps
HERE = Path(__file__).resolve()

# sha256 (first 16 hex digits) of `portable_digest`'s results, recorded when the kernels were
# written: inputs from Python's `random.Random(seed).random()` (the same sequence in every
# Python) combined by IEEE arithmetic only, so these are the bits on any x86-64 machine. A
# deliberate change of a kernel's arithmetic changes it: record the new value then.
RECORDED_DIGEST = "4bb4eb678ff01575"


# -- inputs of the kinds the model has -------------------------------------------------------
def _u(r: random.Random, lo: float, hi: float) -> float:
    return lo + (hi - lo) * r.random()


def gear_like(seed: int, n: int = 6, coords: str = "angle"):
    """(M, K, g): M = diag(m1, m1, J1, m2, m2, J2) with masses 1-10 kg and inertias
    0.005-0.05 kg m^2 (``coords="angle"``; "line": the model's J/rb^2 in kg), K = diag(kb)
    + km g g^T with kb 1e8-1e10 N/m, torsional supports, km 0.5e9-2e9 N/m; g = (0, 1, rb1,
    0, -1, rb2) (angle) or (0, 1, 1, 0, -1, 1) (line). n = 6 or 2 (u1, u2 only)."""
    r = random.Random(seed)
    m1, m2 = _u(r, 1.0, 10.0), _u(r, 1.0, 10.0)
    rb1, rb2 = _u(r, 0.03, 0.1), _u(r, 0.05, 0.2)
    J1, J2 = _u(r, 0.005, 0.05), _u(r, 0.005, 0.05)
    kb1, kb2 = _u(r, 1e8, 1e10), _u(r, 1e8, 1e10)
    kr1, kr2 = _u(r, 0.0, 1e6), _u(r, 1e5, 1e7)  # N m/rad
    km = _u(r, 0.5e9, 2e9)
    if coords == "angle":
        mdiag = [m1, m1, J1, m2, m2, J2]
        kdiag = [kb1, kb1, kr1, kb2, kb2, kr2]
        g = [0.0, 1.0, rb1, 0.0, -1.0, rb2]
    else:
        mdiag = [m1, m1, J1 / (rb1 * rb1), m2, m2, J2 / (rb2 * rb2)]
        kdiag = [kb1, kb1, kr1 / (rb1 * rb1), kb2, kb2, kr2 / (rb2 * rb2)]
        g = [0.0, 1.0, 1.0, 0.0, -1.0, 1.0]
    keep = [2, 5] if n == 2 else list(range(6))
    M = np.diag([mdiag[i] for i in keep])
    K = np.diag([kdiag[i] for i in keep]) + km * dl.outer(np.array(g)[keep],
                                                          np.array(g)[keep])
    return M, K, np.array(g)[keep]


def stick_like(seed: int):
    """(Mt, Kt) = (P M T, P K T) of a gear-like pair (line coordinates) as
    `modal.stick_matrices` builds them for the paper's sliding: x2 tied to x1, friction
    eliminated with lever arms s1m/rb1, s2m/rb2 in (-0.5, 0.5)."""
    r = random.Random(1000 + seed)
    M, K, _ = gear_like(seed, coords="line")
    a1, a2 = _u(r, -0.5, 0.5), _u(r, -0.5, 0.5)
    T = np.zeros((6, 5))
    T[0, 0] = T[3, 0] = 1.0
    T[1, 1] = T[2, 2] = T[4, 3] = T[5, 4] = 1.0
    P = np.zeros((5, 6))
    P[0, 0] = P[0, 3] = 1.0
    P[1, 1] = 1.0
    P[2, 2], P[2, 0] = 1.0, a1
    P[3, 4] = 1.0
    P[4, 5], P[4, 3] = 1.0, -a2
    return dl.matmul(dl.matmul(P, M), T), dl.matmul(dl.matmul(P, K), T)


def spline_data(seed: int, n: int):
    """Strictly increasing knots (spacing 0.2-1.8 of the mean) and values of a stiffness-like
    curve with noise."""
    r = random.Random(2000 + seed)
    x = [0.0]
    for _ in range(n - 1):
        x.append(x[-1] + _u(r, 0.2, 1.8))
    y = [1e9 * (1.0 + 0.3 * (t / x[-1]) * (1.0 - t / x[-1])) + _u(r, -1e6, 1e6) for t in x]
    return np.array(x), np.array(y)


# -- digests of the results (compared between processes) -------------------------------------
def _digest(parts) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(np.ascontiguousarray(p, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def _statuses(*calls):
    return [float(c) for c in calls]


def portable_digest() -> str:
    """Every kernel on inputs built from `random.Random` by IEEE arithmetic (no libm)."""
    parts = []
    for seed in range(6):
        for n, coords in ((6, "angle"), (6, "line"), (2, "line")):
            M, K, g = gear_like(seed, n, coords)
            f = np.array([float(i + 1) for i in range(n)])
            lam, V = dl.eigh_generalized(K, M)
            parts += [lam, V, dl.cholesky(K), dl.solve(K, f), dl.solve(K, np.c_[f, g]),
                      dl.matmul(K, M), dl.matvec(K, f), dl.outer(g, f)]
        Mt, Kt = stick_like(seed)
        parts += list(dl.eig_real_general(Kt, Mt))
        parts.append(dl.null_space_row(gear_like(seed)[2] + np.array([-1, 0, 0, 1, 0, 0.0])))
        for n in (2, 3, 4, 41, 500):
            parts.append(dl.cubic_spline_not_a_knot(*spline_data(seed, n)))
    # the flags too
    sing = np.array([[1.0, 2.0], [2.0, 4.0]])
    parts.append(_statuses(
        dl.solve_entry(sing, np.ones(2), np.empty(2), np.empty((2, 3))),
        dl.cholesky_entry(-np.eye(2), np.empty((2, 2))),
        dl.eig_real_general_entry(np.array([[0.0, 1.0], [-1.0, 0.0]]), np.eye(2),
                                  np.empty(2), np.empty(2), np.empty((2, 2)),
                                  np.empty(dl.work_shape("eig_real_general", 2)))))
    return _digest(parts)


def model_matrices():
    """The model's slip and stick (paper and full sliding) matrices and stiffness knots."""
    from gearpair.potential_energy import pair_stiffness_raw
    from gearpair.stiffness import N_SPLINE

    model = modal.as_model(GearParams())
    M, K = modal.slip_matrices(model)
    Mt, _, Kt, _, _ = modal.stick_matrices(model)
    full = modal.as_model(GearParams(), Effects(sliding="full"))
    xi = np.linspace(0.0, model.geom.path_length, N_SPLINE)
    k = pair_stiffness_raw(model.p, model.geom, xi)
    return model, full, M, K, Mt, Kt, xi, k


def model_inputs() -> dict[str, np.ndarray]:
    """The model's matrices the digest takes (the stiffness knots' values come through
    numpy's BLAS, so a child takes the parent's, saved)."""
    model, full, M, K, Mt, Kt, xi, k = model_matrices()
    s1m, s2m = full.geom.arms(full.geom.xi_pitch)
    w = full.friction_directions(np.array([float(s1m)]), np.array([float(s2m)]))[0]
    return dict(M=M, K=K, Mt=Mt, Kt=Kt, w=w, xi=xi, k=k, f=model.load(1000.0))


def model_digest(inputs: dict[str, np.ndarray]) -> str:
    """The kernels on the model's own matrices."""
    a = inputs
    parts = list(dl.eigh_generalized(a["K"], a["M"])) + list(dl.eig_real_general(a["Kt"],
                                                                                a["Mt"]))
    parts += [dl.null_space_row(a["w"]), dl.cubic_spline_not_a_knot(a["xi"], a["k"]),
              dl.solve(a["K"], a["f"])]
    return _digest(parts)


# -- products ---------------------------------------------------------------------------------
def test_products_match_numpy_within_rounding():
    rng = np.random.default_rng(1)
    for m, p, n in ((6, 6, 6), (5, 6, 5), (1, 3, 7), (6, 1, 6)):
        A, B = rng.standard_normal((m, p)), rng.standard_normal((p, n))
        bound = p * EPS * (np.abs(A) @ np.abs(B))
        assert np.all(np.abs(dl.matmul(A, B) - A @ B) <= bound)
        x = B[:, 0]
        assert np.all(np.abs(dl.matvec(A, x) - A @ x) <= p * EPS * (np.abs(A) @ np.abs(x)))
        assert np.array_equal(dl.outer(A[:, 0], B[0]), np.multiply.outer(A[:, 0], B[0]))
    with pytest.raises(ValueError):
        dl.matmul(np.ones((2, 3)), np.ones((2, 3)))


def test_products_sum_in_index_order_without_fused_multiply_add():
    # the compiled sums are exactly the Python loops (each product and sum rounded, k
    # ascending from 0.0): no reassociation, no FMA, whatever the CPU offers
    rng = np.random.default_rng(2)
    A, B = rng.standard_normal((6, 6)) * 1e5, rng.standard_normal((6, 6)) * 1e-3
    ref = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for k in range(6):
                acc += float(A[i, k]) * float(B[k, j])
            ref[i, j] = acc
    assert np.array_equal(dl.matmul(A, B), ref)


# -- linear systems ---------------------------------------------------------------------------
def test_solve_matches_numpy_with_a_small_residual():
    rng = np.random.default_rng(3)
    for n in range(1, 7):
        for _ in range(20):
            A = rng.standard_normal((n, n))
            b = rng.standard_normal((n, 3))
            x = dl.solve(A, b)
            ref = np.linalg.solve(A, b)
            cond = np.linalg.cond(A)
            assert np.max(np.abs(x - ref)) <= 50 * n * EPS * cond * np.max(np.abs(ref))
            # backward stable: residual at rounding level of |A| |x|
            res = np.abs(A @ x - b)
            assert np.all(res <= 20 * n * EPS * (np.abs(A) @ np.abs(x) + np.abs(b)))
            assert np.array_equal(dl.solve(A, b[:, 0]), x[:, 0])  # one column as several
    for seed in range(4):  # the model's kind: K of a gear pair
        M, K, g = gear_like(seed, coords="line")
        x = dl.solve(K, g)
        ref = np.linalg.solve(K, g)
        assert np.max(np.abs(x - ref)) <= 100 * EPS * np.linalg.cond(K) * np.max(np.abs(ref))


def test_solve_flags_a_singular_or_non_finite_system():
    sing = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [1.0, 0.0, 1.0]])
    assert dl.solve_entry(sing, np.ones(3), np.empty(3), np.empty((3, 4))) == dl.SINGULAR
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        dl.solve(sing, np.ones(3))
    with pytest.raises(np.linalg.LinAlgError, match="non-finite"):
        dl.solve(np.array([[1.0, np.nan], [0.0, 1.0]]), np.ones(2))
    assert dl.solve_entry(np.eye(3), np.ones(3), np.empty(3), np.empty((2, 4))) == \
        dl.BAD_SHAPE


def test_cholesky_matches_numpy_and_flags_indefinite():
    rng = np.random.default_rng(4)
    for n in range(1, 7):
        X = rng.standard_normal((n, n))
        A = X @ X.T + n * np.eye(n)
        L = dl.cholesky(A)
        assert np.allclose(L, np.linalg.cholesky(A), rtol=0, atol=20 * EPS * np.max(L))
        assert np.array_equal(L, np.tril(L))
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        dl.cholesky(np.array([[1.0, 2.0], [2.0, 1.0]]))


# -- symmetric generalized eigenproblem -------------------------------------------------------
def _check_eigh(K, M, lam, V, tol=50):
    n = len(lam)
    assert np.all(np.diff(lam) >= 0)
    # M-orthonormal, and K V = M V diag(lam) at rounding level
    assert np.max(np.abs(V.T @ M @ V - np.eye(n))) <= tol * n * EPS
    res = K @ V - (M @ V) * lam
    scale = np.abs(K) @ np.abs(V) + np.abs(M) @ np.abs(V) * np.abs(lam)
    assert np.all(np.abs(res) <= tol * n * EPS * np.max(scale, axis=0))
    # sign convention: the largest component of each vector is positive
    assert np.all(V[np.argmax(np.abs(V), axis=0), np.arange(n)] > 0)


def test_eigh_generalized_matches_scipy_on_gear_like_matrices():
    for seed in range(10):
        for n, coords in ((6, "angle"), (6, "line"), (2, "angle")):
            M, K, _ = gear_like(seed, n, coords)
            lam, V = dl.eigh_generalized(K, M)
            ref, Vr = sla.eigh(K, M)
            # Weyl: each eigenvalue to rounding of the largest one (both solvers)
            assert np.all(np.abs(lam - ref) <= 50 * n * EPS * np.max(np.abs(ref)))
            _check_eigh(K, M, lam, V)
            # the vectors (distinct eigenvalues): scipy's up to the sign, to rounding / gap
            gap = np.min(np.diff(ref)) / np.max(np.abs(ref))
            Vr = Vr * np.sign(Vr[np.argmax(np.abs(Vr), axis=0), np.arange(n)])
            rel = np.max(np.abs(V - Vr)) / np.max(np.abs(Vr))
            assert rel <= 100 * n * EPS / gap


def test_eigh_generalized_on_the_model_matches_modal_and_exact_values():
    import mpmath

    model, _, M, K, *_ = model_matrices()
    lam, V = dl.eigh_generalized(K, M)
    _check_eigh(K, M, lam, V)
    freqs = np.sqrt(lam) / (2 * np.pi)
    ref = modal.natural_frequencies(model, "slip")
    # scipy's own error on the 32 Hz mode is 2.3e-12 here (eps ||C|| / lam_1)
    assert np.max(np.abs(freqs / ref - 1)) <= 5e-12
    # against 40-digit values: within 1e-12 relative (Jacobi keeps the relative accuracy of
    # the small eigenvalues that the Householder tridiagonalization of scipy's eigh loses)
    mpmath.mp.dps = 40
    C = mpmath.matrix(6, 6)
    for i in range(6):
        for j in range(6):
            C[i, j] = mpmath.mpf(K[i, j]) / mpmath.sqrt(mpmath.mpf(M[i, i]) * M[j, j])
    exact = np.array(sorted(float(e) for e in mpmath.eigsy(C, eigvals_only=True)))
    assert np.max(np.abs(lam / exact - 1)) <= 1e-12
    # the torsional model (u1, u2)
    tors = modal.as_model(GearParams(), Effects(dof="torsional", sliding="full"))
    Mf, Kf = modal.slip_matrices(tors)
    free = tors.free_dofs
    lam2, _ = dl.eigh_generalized(Kf[np.ix_(free, free)], Mf[np.ix_(free, free)])
    ref2 = modal.natural_frequencies(tors, "slip")
    assert np.max(np.abs(np.sqrt(lam2) / (2 * np.pi) / ref2 - 1)) <= 1e-12


def test_eigh_generalized_flags_a_mass_matrix_that_is_not_positive_definite():
    M, K, _ = gear_like(0)
    M[2, 2] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        dl.eigh_generalized(K, M)


# -- general real eigenproblem ----------------------------------------------------------------
def _check_eig(K, M, lam, V, tol=200):
    n = len(lam)
    assert np.all(np.diff(lam) >= 0)
    assert np.allclose(np.linalg.norm(V, axis=0), 1.0, rtol=0, atol=10 * n * EPS)
    assert np.all(V[np.argmax(np.abs(V), axis=0), np.arange(n)] > 0)
    res = K @ V - (M @ V) * lam
    scale = np.abs(K) @ np.abs(V) + np.abs(M) @ np.abs(V) * np.abs(lam)
    assert np.all(np.abs(res) <= tol * n * EPS * np.max(scale))


def test_eig_real_general_matches_scipy_on_stick_like_pencils():
    for seed in range(10):
        Mt, Kt = stick_like(seed)
        lam, V = dl.eig_real_general(Kt, Mt)
        w, Vr = sla.eig(Kt, Mt)
        assert np.max(np.abs(w.imag)) == 0
        order = np.argsort(w.real)
        ref, Vr = w.real[order], Vr[:, order].real
        cond = np.linalg.cond(Mt)
        assert np.all(np.abs(lam - ref) <= 100 * EPS * cond * np.max(np.abs(ref)))
        _check_eig(Kt, Mt, lam, V)
        Vr = Vr / np.linalg.norm(Vr, axis=0)
        Vr = Vr * np.sign(Vr[np.argmax(np.abs(Vr), axis=0), np.arange(5)])
        gap = np.min(np.diff(ref)) / np.max(np.abs(ref))
        assert np.max(np.abs(V - Vr)) <= 1000 * EPS * cond / gap


def test_eig_real_general_on_the_model_matches_modal_and_exact_values():
    import mpmath

    model, full, *_, Mt, Kt, _, _ = model_matrices()
    lam, V = dl.eig_real_general(Kt, Mt)
    _check_eig(Kt, Mt, lam, V)
    freqs = np.sqrt(lam) / (2 * np.pi)
    assert np.max(np.abs(freqs / modal.natural_frequencies(model, "stick") - 1)) <= 1e-12
    mpmath.mp.dps = 40
    A = mpmath.inverse(mpmath.matrix(Mt.tolist())) * mpmath.matrix(Kt.tolist())
    exact = np.array(sorted(float(mpmath.re(e)) for e in mpmath.eig(A, left=False,
                                                                   right=False)))
    assert np.max(np.abs(lam / exact - 1)) <= 1e-12
    # the mode shapes of modal.modes (T v, largest component 1)
    _, shapes = modal.modes(model, "stick")
    _, _, _, _, T = modal.stick_matrices(model)
    mine = T @ V
    mine = mine / mine[np.argmax(np.abs(mine), axis=0), np.arange(5)]
    assert np.max(np.abs(mine - shapes)) <= 1e-10
    # a 1 x 1 problem (the torsional stuck pair)
    lam1, V1 = dl.eig_real_general(np.array([[3.0]]), np.array([[2.0]]))
    assert lam1[0] == 1.5 and V1[0, 0] == 1.0


def test_eig_real_general_flags_complex_eigenvalues():
    K = np.array([[0.0, 1.0], [-1.0, 0.0]])
    lam, lam_imag = np.empty(2), np.empty(2)
    st = dl.eig_real_general_entry(K, np.eye(2), lam, lam_imag, np.empty((2, 2)),
                                   np.empty(dl.work_shape("eig_real_general", 2)))
    assert st == dl.COMPLEX
    assert sorted(lam_imag) == [-1.0, 1.0] and list(lam) == [0.0, 0.0]
    with pytest.raises(ArithmeticError, match="complex"):
        dl.eig_real_general(K, np.eye(2))
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        dl.eig_real_general(K, np.zeros((2, 2)))


# -- null space of a row ----------------------------------------------------------------------
def test_null_space_row_is_an_orthonormal_basis_like_scipys():
    rng = np.random.default_rng(5)
    rows = [rng.standard_normal(n) for n in (2, 3, 5, 6) for _ in range(5)]
    rows += [np.array([0.0, 0.0, 3.0, 0.0]), np.array([-1.0, 0.0, 0.3, 1.0, 0.0, -0.2])]
    for w in rows:
        n = len(w)
        N = dl.null_space_row(w)
        assert N.shape == (n, n - 1)
        assert np.max(np.abs(N.T @ N - np.eye(n - 1))) <= 4 * n * EPS
        assert np.max(np.abs(w @ N)) <= 4 * n * EPS * np.max(np.abs(w))
        Z = sla.null_space(w[None])  # the same space: the same projector
        assert np.max(np.abs(N @ N.T - Z @ Z.T)) <= 20 * n * EPS
        assert np.all(N[np.argmax(np.abs(N), axis=0), np.arange(n - 1)] > 0)
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        dl.null_space_row(np.zeros(3))


def test_stick_modes_of_full_sliding_from_the_null_space_match_modal():
    # sliding = "full": T = null space of the friction row, Mt = T^T M T, Kt = T^T K T
    # (symmetric): the set-up of modal.stick_matrices done by detlinalg alone
    _, full, *_ = model_matrices()
    s1m, s2m = full.geom.arms(full.geom.xi_pitch)
    w = full.friction_directions(np.array([float(s1m)]), np.array([float(s2m)]))[0]
    M, K = modal.slip_matrices(full)
    T = dl.null_space_row(w)
    Tt = np.ascontiguousarray(T.T)
    lam, _ = dl.eigh_generalized(dl.matmul(dl.matmul(Tt, K), T), dl.matmul(dl.matmul(Tt, M), T))
    ref = modal.natural_frequencies(full, "stick")
    assert np.max(np.abs(np.sqrt(lam) / (2 * np.pi) / ref - 1)) <= 1e-12


# -- cubic splines ----------------------------------------------------------------------------
def _spline_close(c, ref, x, y):
    # each coefficient column to rounding of the data it is made of (c_k ~ y / h^k)
    h = np.min(np.diff(x))
    for k in range(4):
        scale = np.max(np.abs(y)) / h ** k
        assert np.max(np.abs(c[:, k] - ref[:, k])) <= 1e3 * EPS * scale, k


def test_cubic_spline_matches_scipys_not_a_knot_spline():
    for seed in range(5):
        for n in (2, 3, 4, 5, 6, 41, 3000):
            x, y = spline_data(seed, n)
            c = dl.cubic_spline_not_a_knot(x, y)
            ref = CubicSpline(x, y).c[::-1].T
            assert c.shape == ref.shape == (n - 1, 4)
            _spline_close(c, ref, x, y)
            assert np.array_equal(c[:, 0], y[:-1])
            # continuity of value, slope and curvature at the inner knots
            h = np.diff(x)[:-1]
            end = ((c[:-1, 3] * h + c[:-1, 2]) * h + c[:-1, 1]) * h + c[:-1, 0]
            assert np.allclose(end, y[1:-1], rtol=1e-13, atol=0)


def test_cubic_spline_reproduces_a_cubic_exactly_to_rounding():
    x = np.cumsum(np.r_[0.0, np.linspace(0.5, 1.5, 30)])
    y = 2.0 - 3.0 * x + 0.5 * x ** 2 + 0.25 * x ** 3
    c = dl.cubic_spline_not_a_knot(x, y)
    assert np.allclose(c[:, 3], 0.25, rtol=1e-10)
    assert np.allclose(c[:, 1], -3.0 + x[:-1] + 0.75 * x[:-1] ** 2, rtol=1e-11)


def test_cubic_spline_of_the_model_stiffness_matches_stiffness_py():
    from gearpair.stiffness import MeshStiffness

    model, *_, xi, k = model_matrices()
    c = dl.cubic_spline_not_a_knot(xi, k)
    ref = CubicSpline(xi, k).c[::-1].T
    _spline_close(c, ref, xi, k)
    # MeshStiffness scales the same spline to the mean stiffness
    law = MeshStiffness.build(model.p, model.geom, Effects().stiffness)
    ratio = law.cubic[:, 0] / c[:, 0]
    assert np.allclose(law.cubic, c * ratio[0], rtol=0, atol=1e-11 * np.max(np.abs(law.cubic),
                                                                           axis=0))


def test_cubic_spline_flags_knots_that_do_not_increase():
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        dl.cubic_spline_not_a_knot([0.0, 1.0, 1.0, 2.0], [1.0, 2.0, 3.0, 4.0])
    with pytest.raises(ValueError):
        dl.cubic_spline_not_a_knot([0.0], [1.0])


# -- compiled callers -------------------------------------------------------------------------
def test_kernels_link_into_other_compiled_code_with_the_same_bits():
    import numba

    @numba.njit(cache=False)
    def static_deflection(K, f, x, W, N, w):
        st = dl.solve_into(K, f, x, W)
        return st if st != dl.OK else dl.null_space_row_into(w, N)

    inputs = model_inputs()
    x, W = np.empty(6), np.empty(dl.work_shape("solve", 6))
    N = np.empty((6, 5))
    assert static_deflection(inputs["K"], inputs["f"], x, W, N, inputs["w"]) == dl.OK
    assert np.array_equal(x, dl.solve(inputs["K"], inputs["f"]))
    assert np.array_equal(N, dl.null_space_row(inputs["w"]))
    # the kernels themselves are compiled-only (jitlink): a TypeError from Python
    if isinstance(dl.solve_into, numba.core.dispatcher.Dispatcher):
        with pytest.raises(TypeError, match="internal function"):
            dl.solve_into(np.eye(2), np.ones(2), np.empty(2), np.empty((2, 3)))


# -- the same bits elsewhere ------------------------------------------------------------------
_CHILD = ("import importlib.util, sys\n"
          "spec = importlib.util.spec_from_file_location('detlinalg_child', sys.argv[1])\n"
          "m = importlib.util.module_from_spec(spec)\n"
          "spec.loader.exec_module(m)\n"
          "import numpy as np\n"
          "print(m.portable_digest(), m.model_digest(dict(np.load(sys.argv[2]))))\n")


def _child(env_extra: dict, inputs: Path) -> subprocess.Popen:
    env = dict(os.environ, GEARPAIR_SHIPPED_CODE="0", GEARPAIR_COMPILE_NOTICE="", **env_extra)
    return subprocess.Popen([sys.executable, "-c", _CHILD, str(HERE), str(inputs)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=str(HERE.parent))


def _result(proc: subprocess.Popen) -> list[str]:
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-3000:]
    return out.split()


@pytest.fixture(scope="module", autouse=True)
def children(tmp_path_factory):
    """Children started with the first test of this file, so that they compile while the
    tests run: code for a plain x86-64 CPU (its own cache folder, kept between runs) and the
    Python reading of the source. Ended at the end of the file if still running. They take
    this process's model matrices (`model_inputs`), which numpy's BLAS makes differ by a
    last bit under another OpenBLAS core."""
    from gearpair.shipped import user_cache_dir

    inputs = tmp_path_factory.mktemp("detlinalg") / "model_inputs.npz"
    np.savez(inputs, **model_inputs())
    base = user_cache_dir()
    plain_cache = os.path.join(base, "detlinalg-test-x86-64") if base else None
    procs = {"plain": _child(dict(NUMBA_CPU_NAME="x86-64", NUMBA_CPU_FEATURES="",
                                  **({"NUMBA_CACHE_DIR": plain_cache} if plain_cache else {})),
                            inputs),
             "python": _child(dict(NUMBA_DISABLE_JIT="1"), inputs)}
    yield dict(procs, inputs=inputs)
    for proc in procs.values():
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


@pytest.fixture(scope="module")
def digests(children):
    """This process's digests, then a child under another OpenBLAS core (started now, when
    this process has cached its code)."""
    here = [portable_digest(), model_digest(dict(np.load(children["inputs"])))]
    prescott = _child(dict(OPENBLAS_CORETYPE="Prescott"), children["inputs"])
    yield dict(children, here=here, prescott=prescott)
    if prescott.poll() is None:
        prescott.kill()
        prescott.communicate()


def test_same_bits_under_another_openblas_core(digests):
    assert _result(digests["prescott"]) == digests["here"]


def test_same_bits_compiled_for_a_plain_x86_64_cpu(digests):
    # SSE2 only (no AVX, no FMA) against this CPU's code (FMA here if the CPU has it)
    assert _result(digests["plain"]) == digests["here"]


def test_same_bits_as_the_python_reading_of_the_source(digests):
    # NUMBA_DISABLE_JIT: every operation rounded as the source writes it, in its order
    assert _result(digests["python"]) == digests["here"]


def test_same_bits_as_recorded(digests):
    assert digests["here"][0] == RECORDED_DIGEST
