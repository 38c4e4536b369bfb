"""gearpair.fast.detmath: the engine's own elementary functions, within 1 ulp of the exact
value, with C99's special values, and the same bits whatever the CPU.

Accuracy is measured against mpmath at 200 bits: ``N`` = 100,000 seeded random arguments per
function (ranges chosen per function: magnitudes log-uniform over the whole double range,
dense near 0, near 1 for log and pow, near multiples of pi/2 for sin/cos/tan, near +-1 for
asin/acos, around the overflow and underflow thresholds), plus each function's edge cases.
mpmath (pure Python here) takes some 50 us a value, so the reference values are computed
once per session, on two processes, and functions that share arguments share them
(exp/expm1, sinh/cosh, sin/cos/tan, asin/acos): about 25 s of the file's 45 s.

Run directly to print the worst error per function and the speed against glibc:

    .venv/bin/python tests/test_detmath.py
"""

from __future__ import annotations

import math
import multiprocessing
import os
import re
import subprocess
import sys
import time

import numba
import numpy as np
import pytest
from mpmath import libmp

from gearpair.fast import detmath

N = 100_000  # random arguments per function (and per group of functions sharing them)
SEED = 20261128
PREC = 200  # bits of the mpmath reference
MAX_ULP = 1.0
RN = libmp.round_nearest
DBL_MAX = sys.float_info.max
DBL_MIN = sys.float_info.min
TRUE_MIN = 5e-324
UNARY = ("exp", "log", "tanh", "sin", "cos", "tan", "asin", "acos", "atan", "expm1", "log1p",
         "sinh", "cosh")
BINARY = ("pow", "atan2")


# -- compiled kernels: detmath's functions are callable from compiled code only -----------------
def _unary_kernel(f):
    @numba.njit(error_model="numpy")
    def kernel(xs, out):
        for i in range(xs.size):
            out[i] = f(xs[i])

    return kernel


def _binary_kernel(f):
    @numba.njit(error_model="numpy")
    def kernel(xs, ys, out):
        for i in range(xs.size):
            out[i] = f(xs[i], ys[i])

    return kernel


KERNELS = {name: _unary_kernel(getattr(detmath, name)) for name in UNARY}
KERNELS.update({name: _binary_kernel(getattr(detmath, name)) for name in BINARY})


def run(name: str, *args: np.ndarray) -> np.ndarray:
    """detmath's ``name`` over the arrays ``args`` (compiled)."""
    args = [np.ascontiguousarray(a, dtype=np.float64) for a in args]
    out = np.empty_like(args[0])
    KERNELS[name](*args, out)
    return out


# -- arguments ---------------------------------------------------------------------------------
def _log_uniform(rng, n, lo, hi, signed=True):
    """n doubles with binary exponents uniform in [lo, hi) and random 52-bit mantissas
    (exponents below -1022 give subnormals)."""
    x = np.ldexp(1.0 + rng.integers(0, 2**52, n) * 2.0**-52, rng.integers(lo, hi, n))
    return x * rng.choice([-1.0, 1.0], n) if signed else x


def _near(rng, centres, n, lo=-52, hi=-4):
    """n doubles at a log-uniform relative distance (2^lo .. 2^hi, either side) from
    ``centres`` (drawn among them)."""
    c = rng.choice(np.asarray(centres, dtype=float), n)
    return c * (1.0 + _log_uniform(rng, n, lo, hi))


def _mix(rng, n, parts):
    """Concatenate parts (fraction, generator(rng, m)) to n values, shuffled."""
    sizes = [int(f * n) for f, _ in parts]
    sizes[0] += n - sum(sizes)
    out = np.concatenate([g(rng, m) for (_, g), m in zip(parts, sizes, strict=True)])
    rng.shuffle(out)
    return out


EXP_EDGES = [709.782712893384, 709.7827128933841, 709.78, 709.0, -708.3964185322641,
             -708.4, -744.44007192138122, -745.1332191019411, -745.1332191019412, -746.0,
             -37.5, -38.0, 2.0**-54, -(2.0**-54), 2.0**-53, TRUE_MIN, -TRUE_MIN, DBL_MIN,
             1.0, -1.0, 0.5, 22.0, 710.0 - 2**-40, 512.0, -512.0, 1023.0 * math.log(2)]
LOG_EDGES = [TRUE_MIN, 2 * TRUE_MIN, DBL_MIN, DBL_MIN * (1 - 2**-52), DBL_MAX, 1.0,
             1.0 + 2**-52, 1.0 - 2**-53, 0.5, 2.0, math.e, 0.6875, 1.375, 1.0 + 2**-7,
             1.0 - 2**-8, 10.0, 1e-300, 1e300]
TRIG_EDGES = [math.pi / 4, -math.pi / 4, math.pi / 2, math.pi, 2 * math.pi, 1e22, 1e300,
              DBL_MAX, -DBL_MAX, TRUE_MIN, DBL_MIN, 2.0**-26, 2.0**-27, 1647099.0,
              1647100.0, 2.0**20 * math.pi / 2, 6381956970095103 * 2.0**797, 5.0e-324,
              (math.pi / 2) * 2**20, 355.0, 103993.0, 0.7853981633974483 * 3]


def _exp_args(rng, n):
    return np.concatenate([_mix(rng, n - len(EXP_EDGES), [
        (0.3, lambda r, m: r.uniform(-746.0, 710.0, m)),
        (0.3, lambda r, m: _log_uniform(r, m, -60, 10)),  # dense near 0 (expm1)
        (0.1, lambda r, m: r.uniform(709.0, 709.8, m)),  # overflow
        (0.15, lambda r, m: r.uniform(-746.0, -707.0, m)),  # subnormal results
        (0.05, lambda r, m: _log_uniform(r, m, -1074, -60)),
        (0.1, lambda r, m: r.integers(-95000, 90000, m) * (math.log(2) / 128)
         * (1.0 + _log_uniform(r, m, -52, -30))),  # table boundaries
    ]), EXP_EDGES])


def _log_args(rng, n):
    return np.concatenate([_mix(rng, n - len(LOG_EDGES), [
        (0.45, lambda r, m: _log_uniform(r, m, -1074, 1024, signed=False)),
        (0.15, lambda r, m: 1.0 + r.uniform(-2.0**-6, 2.0**-6, m)),
        (0.15, lambda r, m: 1.0 + _log_uniform(r, m, -53, -6)),  # very near 1
        (0.2, lambda r, m: r.uniform(0.5, 2.0, m)),
        (0.05, lambda r, m: _log_uniform(r, m, -1074, -1022, signed=False)),
    ]), LOG_EDGES])


def _log1p_args(rng, n):
    edges = [-1.0 + 2**-53, -0.5, 2.0**-54, -(2.0**-54), 2.0**-53, TRUE_MIN, DBL_MAX, 1.0,
             -0.2928932188134524, 0.4142135623730950, 2.0**53, 1e300]
    return np.concatenate([_mix(rng, n - len(edges), [
        (0.4, lambda r, m: np.abs(_log_uniform(r, m, -60, 0)) * r.choice([-1.0, 1.0], m)),
        (0.1, lambda r, m: -1.0 + _log_uniform(r, m, -53, -1, signed=False)),  # near -1
        (0.2, lambda r, m: _log_uniform(r, m, 0, 1024, signed=False)),
        (0.1, lambda r, m: _log_uniform(r, m, -1074, -60)),
        (0.2, lambda r, m: r.uniform(-0.5, 2.0, m)),
    ]), edges])


def _pow_args(rng, n):
    def across(r, m):  # any x, y such that the result spans the whole range and beyond
        x = _log_uniform(r, m, -1074, 1024, signed=False)
        return x, r.uniform(-1090.0, 1040.0, m) / np.log2(x)

    def near_one(r, m):  # x near 1, large y
        x = 1.0 + _log_uniform(r, m, -52, -6)
        return x, r.uniform(-1090.0, 1040.0, m) / np.log2(x)

    def ordinary(r, m):
        return r.uniform(0.0, 10.0, m), r.uniform(-30.0, 30.0, m)

    def negative(r, m):  # negative x, integer y
        return -r.uniform(0.01, 10.0, m), r.integers(-300, 300, m).astype(float)

    def integers(r, m):  # exact results where representable
        return r.integers(2, 40, m).astype(float), r.integers(0, 60, m).astype(float)

    def step_control(r, m):  # the engine's err ** expo
        return _log_uniform(r, m, -40, 20, signed=False), r.choice([-0.2, -0.125, -1 / 9,
                                                                  -1 / 8, 1 / 3, 0.5], m)

    parts = [(0.35, across), (0.2, near_one), (0.2, ordinary), (0.1, negative),
             (0.1, integers), (0.05, step_control)]
    xs, ys = [], []
    for f, g in parts:
        x, y = g(rng, int(f * n))
        xs.append(x)
        ys.append(y)
    edges = [(2.0, 1023.0), (2.0, 1024.0), (2.0, -1074.0), (2.0, -1075.0), (2.0, -1022.5),
             (10.0, 308.0), (10.0, -323.0), (DBL_MAX, 1.0), (TRUE_MIN, 1.0), (DBL_MAX, -1.0),
             (0.5, 1074.0), (-2.0, 1023.0), (-2.0, -1073.0), (1.0 + 2**-52, 2.0**52),
             (1.0 - 2**-53, 2.0**53), (3.0, 0.5), (-8.0, 3.0), (9.0, 0.5), (1e-300, 1.03)]
    x = np.concatenate(xs + [np.array([e[0] for e in edges])])
    y = np.concatenate(ys + [np.array([e[1] for e in edges])])
    keep = np.isfinite(y)
    return x[keep][:n], y[keep][:n]


def _tanh_args(rng, n):
    edges = [2.0**-28, 2.0**-27, 19.0, 19.1, 22.0, 21.9, 0.55, TRUE_MIN, DBL_MAX, 1.0]
    return np.concatenate([_mix(rng, n - len(edges), [
        (0.6, lambda r, m: _log_uniform(r, m, -40, 5)),
        (0.3, lambda r, m: r.uniform(-25.0, 25.0, m)),
        (0.1, lambda r, m: _log_uniform(r, m, -1074, -40)),
    ]), edges])


def _hyperbolic_args(rng, n):  # sinh and cosh
    edges = [710.4758600739439, 710.475860073944, 710.47586007394, 709.78, 711.0, 21.0,
             20.999999999999996, 2.0**-26, 2.0**-27, TRUE_MIN, 1.0, -710.4758600739439]
    return np.concatenate([_mix(rng, n - len(edges), [
        (0.5, lambda r, m: _log_uniform(r, m, -40, 10)),
        (0.2, lambda r, m: r.uniform(-711.0, 711.0, m)),
        (0.1, lambda r, m: r.uniform(709.0, 710.5, m) * r.choice([-1.0, 1.0], m)),
        (0.2, lambda r, m: r.uniform(-25.0, 25.0, m)),
    ]), edges])


def _trig_args(rng, n):  # sin, cos and tan
    def near_multiples(r, m):
        k = np.where(r.random(m) < 0.7, r.integers(1, 64, m), r.integers(1, 2**20, m))
        return (k * (math.pi / 2)) * (1.0 + _log_uniform(r, m, -52, -20)) \
            * r.choice([-1.0, 1.0], m)

    return np.concatenate([_mix(rng, n - len(TRIG_EDGES), [
        (0.43, lambda r, m: r.uniform(-10.0, 10.0, m)),
        (0.2, near_multiples),
        (0.15, lambda r, m: _log_uniform(r, m, -30, 21)),
        (0.07, lambda r, m: _log_uniform(r, m, 20, 1024)),  # the Payne-Hanek reduction
        (0.05, lambda r, m: _log_uniform(r, m, -1074, -30)),
        (0.1, lambda r, m: _near(r, [math.pi / 4, 3 * math.pi / 4], m, -52, -10)
         * r.choice([-1.0, 1.0], m)),
    ]), TRIG_EDGES])


def _asin_args(rng, n):  # asin and acos
    edges = [1.0, -1.0, 1.0 - 2**-53, -1.0 + 2**-53, 0.5, -0.5, 2.0**-26, 2.0**-57,
             2.0**-58, TRUE_MIN, 0.9999999999999999, 0.7071067811865476]
    return np.concatenate([_mix(rng, n - len(edges), [
        (0.4, lambda r, m: r.uniform(-1.0, 1.0, m)),
        (0.3, lambda r, m: (1.0 - _log_uniform(r, m, -53, -2, signed=False))
         * r.choice([-1.0, 1.0], m)),
        (0.3, lambda r, m: _log_uniform(r, m, -70, -1)),
    ]), edges])


def _atan_args(rng, n):
    edges = [1.0, -1.0, 2.0**-27, 2.0**-26, 2.0**60, 2.0**59, DBL_MAX, TRUE_MIN, 0.4375,
             1.0 / 32, 31.0 / 32, 33.0 / 32, 1e16]
    return np.concatenate([_mix(rng, n - len(edges), [
        (0.6, lambda r, m: _log_uniform(r, m, -40, 64)),
        (0.3, lambda r, m: r.uniform(-4.0, 4.0, m)),
        (0.1, lambda r, m: _log_uniform(r, m, -1074, 1024)),
    ]), edges])


def _atan2_args(rng, n):
    def wide(r, m):
        return _log_uniform(r, m, -1074, 1024), _log_uniform(r, m, -1074, 1024)

    def close(r, m):  # exponents within 80: the double-double path and its limits
        x = _log_uniform(r, m, -900, 900)
        return x * np.ldexp(r.uniform(0.5, 2.0, m), r.integers(-80, 80, m)), x

    def unit(r, m):
        return r.uniform(-1.0, 1.0, m), r.uniform(-1.0, 1.0, m)

    def axes(r, m):  # near the axes
        t = _log_uniform(r, m, -70, -1)
        s = r.uniform(0.1, 10.0, m) * r.choice([-1.0, 1.0], m)
        first = r.random(m) < 0.5
        return np.where(first, t, s), np.where(first, s, t)

    xs, ys = [], []
    for f, g in [(0.4, wide), (0.2, close), (0.2, unit), (0.2, axes)]:
        y, x = g(rng, int(f * n))
        ys.append(y)
        xs.append(x)
    y = np.concatenate(ys)
    x = np.concatenate(xs)
    keep = (x != 0) | (y != 0)
    return y[keep], x[keep]


# -- reference values ---------------------------------------------------------------------------
_THRESHOLD = libmp.from_man_exp(2**54 - 1, 970)  # 2^1024 - 2^970: rounds to inf from here


def _pack(v):
    """The exact value v (an mpf) as (hi, lo, ulp, s): v 2^-s = hi + lo with s = floor(log2
    |v|) (so 1 <= |hi| <= 2, lo a double: 106 bits or more), ulp the unit in the last place
    of v scaled alike (2^-52, or the subnormals' spacing 2^-1074 scaled); hi = +-inf (s = 0)
    where v rounds to +-inf. Integer arithmetic only (mpmath's conversions cost more)."""
    sign, man, exp, bc = v
    if not man:
        return 0.0, 0.0, 2.0**-1074, 0
    e = exp + bc - 1  # floor(log2 |v|)
    if e >= 1023 and libmp.mpf_cmp(libmp.mpf_abs(v), _THRESHOLD) >= 0:
        return (-math.inf if sign else math.inf), 0.0, math.inf, 0
    if bc <= 53:
        hi, lo = math.ldexp(man, 1 - bc), 0.0
    else:  # man / 2^(bc - 1) rounded to 53 bits, to nearest even, and the rest
        sh = bc - 53
        q, r = man >> sh, man & ((1 << sh) - 1)
        if 2 * r > 1 << sh or (2 * r == 1 << sh and q & 1):
            q, r = q + 1, r - (1 << sh)
        hi, lo = math.ldexp(q, 1 - 53), r / (1 << (bc - 1))
    if sign:
        hi, lo = -hi, -lo
    return hi, lo, 2.0 ** max(-52, -1074 - e), e


def _series(x, coefs):
    """sum c_k x^k (k from 1) at PREC + 20 bits, for tiny x."""
    total, p = libmp.fzero, libmp.fone
    for c in coefs:
        p = libmp.mpf_mul(p, x, PREC + 20, RN)
        total = libmp.mpf_add(total, libmp.mpf_mul(p, c, PREC + 20, RN), PREC + 20, RN)
    return total


_F = libmp.from_rational
EXPM1_SERIES = [_F(1, math.factorial(k), PREC + 20, RN) for k in range(1, 9)]
LOG1P_SERIES = [_F((-1) ** (k + 1), k, PREC + 20, RN) for k in range(1, 10)]
PIO2 = libmp.mpf_shift(libmp.mpf_pi(PREC + 20), -1)


def _exact(name, x, y=None):
    """mpmath's values of the function group ``name`` at x (its first argument; y the
    second of pow and atan2), at PREC bits."""
    X = libmp.from_float(x)
    if name == "exp":  # exp and expm1
        e = libmp.mpf_exp(X, PREC, RN)
        m = _series(X, EXPM1_SERIES) if abs(x) < 2.0**-20 else \
            libmp.mpf_sub(e, libmp.fone, PREC, RN)
        return e, m
    if name == "log":
        return (libmp.mpf_log(X, PREC, RN),)
    if name == "log1p":
        if abs(x) < 2.0**-20:
            return (_series(X, LOG1P_SERIES),)
        return (libmp.mpf_log(libmp.mpf_add(libmp.fone, X), PREC + 40, RN),)
    if name == "pow":
        return (libmp.mpf_pow(X, libmp.from_float(y), PREC, RN),)
    if name == "tanh":
        return (libmp.mpf_tanh(X, PREC, RN),)
    if name == "sinh":  # sinh and cosh
        c, s = libmp.mpf_cosh_sinh(X, PREC, RN)
        return s, c
    if name == "sin":  # sin, cos and tan
        c, s = libmp.mpf_cos_sin(X, PREC, RN)
        return s, c, libmp.mpf_div(s, c, PREC, RN)
    if name == "asin":  # asin and acos
        # atan2(x, sqrt(1 - x^2)): mpmath's asin is twice as slow near +-1
        c = libmp.mpf_sqrt(libmp.mpf_sub(libmp.fone, libmp.mpf_mul(X, X)), PREC + 20, RN)
        a = libmp.mpf_atan2(X, c, PREC + 10, RN)
        return a, libmp.fzero if x == 1.0 else libmp.mpf_sub(PIO2, a, PREC, RN)
    if name == "atan":
        return (libmp.mpf_atan(X, PREC, RN),)
    if name == "atan2":
        return (libmp.mpf_atan2(X, libmp.from_float(y), PREC, RN),)
    raise ValueError(name)


def _reference_chunk(task):
    """Worker: packed exact values (`_pack`) for one chunk of a group's arguments."""
    name, xs, ys = task
    rows = [[_pack(v) for v in _exact(name, x, None if ys is None else ys[i])]
            for i, x in enumerate(xs)]
    return [np.array([r[k] for r in rows]) for k in range(len(rows[0]))]


# group: (its functions, argument generator); binary groups' generators give (x, y)
GROUPS = {"exp": (("exp", "expm1"), _exp_args), "log": (("log",), _log_args),
          "log1p": (("log1p",), _log1p_args), "pow": (("pow",), _pow_args),
          "tanh": (("tanh",), _tanh_args), "sinh": (("sinh", "cosh"), _hyperbolic_args),
          "sin": (("sin", "cos", "tan"), _trig_args), "asin": (("asin", "acos"), _asin_args),
          "atan": (("atan",), _atan_args), "atan2": (("atan2",), _atan2_args)}


def reference(n: int = N, processes: int = 2) -> dict:
    """name -> (args, exact values as arrays (hi, lo, ulp, shift)) for every function, the
    arguments drawn with ``SEED``; mpmath runs on ``processes`` forked workers."""
    rng = np.random.default_rng(SEED)
    args = {}
    tasks = []
    for group, (_, gen) in GROUPS.items():
        a = gen(rng, n)
        args[group] = a if isinstance(a, tuple) else (a,)
        chunks = np.array_split(np.arange(len(args[group][0])), 16)
        for c in chunks:
            xs = args[group][0][c]
            ys = args[group][1][c] if len(args[group]) > 1 else None
            tasks.append((group, xs, ys))
    if processes > 1:
        with multiprocessing.get_context("fork").Pool(processes) as pool:
            results = pool.map(_reference_chunk, tasks, chunksize=1)
    else:
        results = [_reference_chunk(t) for t in tasks]
    out, i = {}, 0
    for group, (names, _) in GROUPS.items():
        parts = results[i:i + 16]
        i += 16
        for k, name in enumerate(names):
            packed = np.concatenate([p[k] for p in parts])
            out[name] = (args[group], tuple(packed[:, j] for j in range(4)))
    return out


def ulp_errors(res: np.ndarray, exact: tuple) -> np.ndarray:
    """|res - exact| in ulps of the exact value (inf where res is NaN, or finite where the
    exact value rounds to inf, or inf where it does not)."""
    hi, lo, ulp, shift = exact
    with np.errstate(invalid="ignore", over="ignore"):
        scaled = np.ldexp(res, -shift.astype(int))
        # inf as 2^1024 (a result past DBL_MAX of a value just below the rounding to inf)
        big = np.isinf(res) & (shift >= 1)
        scaled[big] = np.copysign(np.ldexp(2.0, 1023 - shift[big].astype(int)), res[big])
        err = np.abs((scaled - hi) - lo) / ulp
    over = np.isinf(hi)
    err[over] = np.where(res[over] == hi[over], 0.0, np.inf)
    err[np.isnan(res)] = np.inf
    return err


@pytest.fixture(scope="session")
def exact_values():
    return reference()


# -- accuracy -----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", UNARY + BINARY)
def test_within_one_ulp_of_mpmath(exact_values, name):
    args, exact = exact_values[name]
    res = run(name, *args)
    err = ulp_errors(res, exact)
    worst = int(np.argmax(err))
    at = ", ".join(repr(float(a[worst])) for a in args)
    assert len(err) >= N - 100
    assert err[worst] <= MAX_ULP, f"{name}({at}) = {res[worst]!r}: {err[worst]:.3f} ulp"


def test_the_ulp_measure_can_fail(exact_values):
    """The measure sees one ulp more, a wrong overflow and a NaN."""
    args, exact = exact_values["exp"]
    res = run("exp", *args)
    bumped = np.nextafter(res, np.inf)
    finite = np.isfinite(res) & (res > 1e-300) & (res < 1e300)
    before, after = ulp_errors(res, exact)[finite], ulp_errors(bumped, exact)[finite]
    assert (before + after >= 0.999).all() and after.max() > 1.0
    wrong = res.copy()
    wrong[np.isinf(exact[0])] = DBL_MAX
    wrong[0] = math.nan
    err = ulp_errors(wrong, exact)
    assert np.isinf(err[np.isinf(exact[0])]).all() and np.isinf(err[0])


# -- special values (C99 Annex F) ---------------------------------------------------------------
SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, TRUE_MIN, -TRUE_MIN, DBL_MIN, -DBL_MIN,
           DBL_MAX, -DBL_MAX, 1.0, -1.0, 0.5, -0.5, 2.0, -2.0, 3.0, -3.0, 1e-300, 1e300,
           710.0, -750.0, 709.7827128933841, -745.2, 2.0**53, 2.0**53 + 2, 2.0**60]
NUMPY = {"exp": np.exp, "log": np.log, "tanh": np.tanh, "sin": np.sin, "cos": np.cos,
         "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
         "expm1": np.expm1, "log1p": np.log1p, "sinh": np.sinh, "cosh": np.cosh,
         "pow": np.power, "atan2": np.arctan2}


def _same(a: float, b: float) -> bool:
    """Equal bits (any NaN equals any NaN; the sign of a zero counts)."""
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


def _exact_result(v: float) -> bool:
    """A result C99 fixes exactly: NaN, +-inf, +-0, +-1, or pi, pi/2, pi/4, 3pi/4 rounded
    (atan2's and asin/acos's special values)."""
    return math.isnan(v) or math.isinf(v) or abs(v) in (0.0, 1.0, math.pi, math.pi / 2,
                                                       math.pi / 4, 3 * math.pi / 4)


def _special_cases(name):
    if name in BINARY:
        pts = [(a, b) for a in SPECIAL for b in SPECIAL + [0.25, -0.25, 1.5, 4.0, -4.0]]
        return np.array([p[0] for p in pts]), np.array([p[1] for p in pts])
    return (np.array(SPECIAL),)


def _c_library(name, args):
    """glibc's values: Python's math (libm itself) where it returns one, else numpy's (math
    raises on overflow and domain errors; numpy may use its own SIMD code, exact for these)."""
    with np.errstate(all="ignore"):
        fallback = NUMPY[name](*args)
    f = getattr(math, {"asin": "asin", "acos": "acos"}.get(name, name))
    out = []
    for i in range(len(args[0])):
        try:
            out.append(f(*(float(a[i]) for a in args)))
        except (ValueError, OverflowError):
            out.append(float(fallback[i]))
    return out


@pytest.mark.parametrize("name", UNARY + BINARY)
def test_special_values_are_c99s(name):
    """Where C99 fixes the result exactly (NaN, infinities, zeros with their signs, 1, the
    rounded pi/2 ...), it is bit for bit glibc's; elsewhere within an ulp of it."""
    args = _special_cases(name)
    res = run(name, *args)
    want = _c_library(name, args)
    bad = []
    for i in range(len(res)):
        w, r = want[i], float(res[i])
        if _exact_result(w):
            ok = _same(r, w)
        else:
            ok = math.isfinite(r) and abs(r - w) <= math.ulp(w)
        if not ok:
            bad.append((tuple(float(a[i]) for a in args), r, w))
    assert not bad, f"{name}: (args, detmath, C) {bad[:8]}"


def test_pow_c99_cases():
    """C99 F.10.4.4, case by case."""
    cases = [((-0.0, -3.0), -math.inf), ((0.0, -3.0), math.inf), ((-0.0, -2.0), math.inf),
             ((-0.0, -0.5), math.inf), ((-0.0, 3.0), -0.0), ((-0.0, 2.0), 0.0),
             ((-0.0, 0.5), 0.0), ((-1.0, math.inf), 1.0), ((-1.0, -math.inf), 1.0),
             ((1.0, math.nan), 1.0), ((math.nan, 0.0), 1.0), ((math.nan, -0.0), 1.0),
             ((-2.5, 0.5), math.nan), ((0.5, -math.inf), math.inf),
             ((2.0, -math.inf), 0.0), ((0.5, math.inf), 0.0), ((2.0, math.inf), math.inf),
             ((-math.inf, -3.0), -0.0), ((-math.inf, -2.0), 0.0), ((-math.inf, 3.0), -math.inf),
             ((-math.inf, 2.5), math.inf), ((math.inf, -1.0), 0.0), ((math.inf, 0.1), math.inf),
             ((-8.0, 1.0 / 3.0), math.nan), ((-2.0, 3.0), -8.0), ((-2.0, -1.0), -0.5),
             ((-2.0, 2.0**53 + 2), math.inf), ((-0.5, 2.0**60), 0.0), ((-2.0, 1025.0), -math.inf),
             ((-2.0, -1075.0), -0.0), ((-2.0, -1074.0), 5e-324), ((3.0, 2.0), 9.0),
             ((10.0, 22.0), 1e22), ((2.0, 0.5), math.sqrt(2.0)), ((math.nan, 1.0), math.nan)]
    x = np.array([c[0][0] for c in cases])
    y = np.array([c[0][1] for c in cases])
    res = run("pow", x, y)
    bad = [(c[0], float(r), c[1]) for c, r in zip(cases, res, strict=True)
           if not _same(float(r), c[1])]
    assert not bad


def test_exact_integer_powers():
    """pow of small integers is exact whenever the result is a double."""
    b, e = np.meshgrid(np.arange(2.0, 60.0), np.arange(0.0, 40.0))
    b, e = b.ravel(), e.ravel()
    res = run("pow", b, e)
    want = np.array([float(int(p) ** int(q)) if int(p) ** int(q) < 2**1000 else math.inf
                     for p, q in zip(b, e, strict=True)])
    exact = np.array([int(p) ** int(q) < 2**53 for p, q in zip(b, e, strict=True)])
    assert (res[exact] == want[exact]).all()


# -- the tables and constants, against mpmath ---------------------------------------------------
def test_tables_match_mpmath():
    from mpmath import mp, mpf

    mp.prec = 300
    two = mpf(2)
    for j in range(128):
        t = two ** (mpf(j) / 128)
        assert detmath.EXP_HI[j] == float(t)
        assert detmath.EXP_TAIL[j] == float((t - detmath.EXP_HI[j]) / detmath.EXP_HI[j])
    for i in range(128):
        v = -mp.log(mpf(detmath.LOG_INVC[i]))
        h = mp.nint(v * two**42) / two**42
        assert detmath.LOG_C_H[i] == h and detmath.LOG_C_L[i] == float(v - h)
        assert detmath.LOG_INVC[i] * 2**19 == int(detmath.LOG_INVC[i] * 2**19)
    for j in range(17):
        v = mp.atan(mpf(j) / 16)
        assert detmath.ATAN_H[j] == float(v) and detmath.ATAN_L[j] == float(v - float(v))
    with mp.workprec(1600):
        bits = int(mp.floor(2 / mp.pi * two ** (24 * 60)))
    want = [(bits >> (24 * (59 - i))) & 0xFFFFFF for i in range(60)]
    assert [int(g) for g in detmath.TWO_OVER_PI] == want
    assert abs(detmath.PIO2_1 + mpf(detmath.PIO2_2) + detmath.PIO2_3 + detmath.PIO2_4
               - mp.pi / 2) < two**-150
    for c, bits_max in ((detmath.PIO2_1, 32), (detmath.PIO2_2, 32), (detmath.PIO2_3, 32),
                        (detmath.LN2HI_N, 32), (detmath.LN2_HI, 42)):
        m, _ = math.frexp(c)
        assert (m * 2**bits_max).is_integer()
    assert abs(mpf(detmath.LN2HI_N) + detmath.LN2LO_N - mp.log(2) / 128) < two**-92
    assert abs(mpf(detmath.LN2_HI) + detmath.LN2_LO - mp.log(2)) < two**-95
    assert abs(mpf(detmath.PI_H) + detmath.PI_L - mp.pi) < two**-105


# -- the same bits everywhere -------------------------------------------------------------------
_HASH_SCRIPT = r"""
import hashlib, numba, numpy as np
from gearpair.fast import detmath as dm

@numba.njit(error_model="numpy", cache=True)
def kernel(xs, out):
    for i in range(xs.size):
        x = xs[i]
        y = xs[xs.size - 1 - i]
        out[0, i] = dm.exp(x)
        out[1, i] = dm.log(abs(x))
        out[2, i] = dm.pow(abs(x), y * 0.01)
        out[3, i] = dm.tanh(x)
        out[4, i] = dm.sin(x)
        out[5, i] = dm.cos(x)
        out[6, i] = dm.tan(x)
        out[7, i] = dm.asin(x * 0.001)
        out[8, i] = dm.acos(x * 0.001)
        out[9, i] = dm.atan(x)
        out[10, i] = dm.atan2(x, y)
        out[11, i] = dm.expm1(x * 0.1)
        out[12, i] = dm.log1p(abs(x))
        out[13, i] = dm.sinh(x)
        out[14, i] = dm.cosh(x)

rng = np.random.default_rng(7)
xs = rng.uniform(-700.0, 700.0, 20000) * np.ldexp(1.0, rng.integers(-30, 1, 20000))
out = np.empty((15, xs.size))
kernel(xs, out)
glibc = np.concatenate([np.exp(xs), np.sin(xs), np.tanh(xs)])
print(hashlib.sha256(out.tobytes()).hexdigest(), hashlib.sha256(glibc.tobytes()).hexdigest())
"""


def _hashes(folder, env_extra: dict) -> tuple[str, str]:
    """sha256 of the script's detmath values and of glibc's exp/sin/tanh, in a new process
    (its kernel cached in ``folder``: the second run loads the code the first compiled)."""
    script = folder / "detmath_hash.py"
    script.write_text(_HASH_SCRIPT)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(folder / "cache"), **env_extra)
    out = subprocess.run([sys.executable, str(script)], env=env, check=True,
                         capture_output=True, text=True, timeout=300).stdout.split()
    return out[0], out[1]


def test_same_bits_without_avx2_and_fma(tmp_path):
    """glibc chooses its exp/sin/tanh by the CPU's features; detmath calls no libm, so a run
    with glibc's AVX2/FMA paths disabled gives the same bits (glibc's may differ: shown, not
    asserted)."""
    ours_here, glibc_here = _hashes(tmp_path, {})
    ours, glibc = _hashes(tmp_path, {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F"})
    assert ours == ours_here, "detmath's bits depend on glibc's CPU paths"
    print(f"glibc's exp/sin/tanh {'unchanged' if glibc == glibc_here else 'changed'}")


LIBM = r"(exp|expm1|log|log1p|pow|sin|cos|tan|sinh|cosh|tanh|asin|acos|atan|atan2)"


def test_no_fma_and_no_libm_in_the_compiled_code():
    """fastmath is off, so LLVM contracts no a * b + c into an FMA: not one in the code of
    any function (the host CPU here may well have FMA); and none calls the C library's
    elementary functions."""
    fma = ("vfmadd", "vfmsub", "vfnmadd", "vfnmsub")
    for name, kernel in KERNELS.items():
        if not kernel.signatures:
            run(name, *([np.ones(4)] * (2 if name in BINARY else 1)))
        asm = kernel.inspect_asm(kernel.signatures[0])
        assert not any(op in asm for op in fma), name
        assert not re.findall(r"(?:call\w*|movabsq)\s+\$?" + LIBM + r"\b", asm), name


def test_python_callers_are_refused():
    with pytest.raises(TypeError):
        detmath.exp(1.0)


# -- run directly: errors and speed ---------------------------------------------------------------
def _bench_kernel(f):
    @numba.njit(error_model="numpy")
    def kernel(xs):
        s = 0.0
        for i in range(xs.size):
            s += f(xs[i])
        return s

    return kernel


def _speed() -> None:
    import math as m

    funcs = {"exp": (detmath.exp, m.exp, (-700.0, 700.0)), "tanh": (detmath.tanh, m.tanh,
             (-5.0, 5.0)), "log": (detmath.log, m.log, (1e-3, 1e3)),
             "sin": (detmath.sin, m.sin, (-10.0, 10.0))}
    xs = np.random.default_rng(1).uniform(0.0, 1.0, 1_000_000)
    for name, (ours, theirs, (a, b)) in funcs.items():
        x = a + (b - a) * xs
        t = []
        for f in (ours, theirs):
            k = _bench_kernel(f)
            k(x[:10])
            t0 = time.perf_counter()
            for _ in range(5):
                k(x)
            t.append((time.perf_counter() - t0) / 5 / x.size * 1e9)
        print(f"{name:6s} detmath {t[0]:5.1f} ns   glibc {t[1]:5.1f} ns")

    @numba.njit(error_model="numpy")
    def pow_ours(xs, y):
        s = 0.0
        for i in range(xs.size):
            s += detmath.pow(xs[i], y)
        return s

    @numba.njit(error_model="numpy")
    def pow_glibc(xs, y):
        s = 0.0
        for i in range(xs.size):
            s += xs[i] ** y
        return s

    x = 1e-8 + 10.0 * xs
    t = []
    for k in (pow_ours, pow_glibc):
        k(x[:10], -0.2)
        t0 = time.perf_counter()
        for _ in range(5):
            k(x, -0.2)
        t.append((time.perf_counter() - t0) / 5 / x.size * 1e9)
    print(f"pow    detmath {t[0]:5.1f} ns   glibc {t[1]:5.1f} ns")


if __name__ == "__main__":
    t0 = time.perf_counter()
    ex = reference()
    print(f"reference values: {time.perf_counter() - t0:.1f} s")
    for fname in UNARY + BINARY:
        a, e = ex[fname]
        err = ulp_errors(run(fname, *a), e)
        w = int(np.argmax(err))
        print(f"{fname:6s} max {err[w]:.4f} ulp over {err.size} points at "
              f"{', '.join(repr(float(v[w])) for v in a)}")
    _speed()
