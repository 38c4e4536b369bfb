"""Elementary functions and sums for the Python around the model's set-up (`fast.setup`).

The model's set-up (gear geometry, the potential-energy stiffness, its spline, the static
equilibrium, the highest natural frequency that bounds the step) must give the same bits on
every machine, as the engine does. Python's ``math`` and numpy's ``sin``, ``exp``, ... call
the C library or numpy's own SIMD code, both chosen by CPU features, and numpy's sums and
products of small matrices go through code whose order of operations depends on the CPU or
the BLAS kernel. Here the set-up gets the project's own elementary functions (`detmath`:
IEEE operations only) over arrays or scalars and row sums in a fixed order.

Each function takes a float or an array and returns the same kind; the compiled work is one
entry point per kind of loop (`_apply`, `_row_sums`), so a first compile stays short.
"""

from __future__ import annotations

import numpy as np

from ..jitcache import jit_entry
from . import detmath as dm

SIN, COS, TAN, ASIN, ACOS, ATAN, EXP, LOG, TANH = range(9)


@jit_entry
def _apply(code, x, out):
    """out[i] = f(x[i]) for the function ``code``."""
    for i in range(x.size):
        v = x[i]
        if code == SIN:
            r = dm.sin(v)
        elif code == COS:
            r = dm.cos(v)
        elif code == TAN:
            r = dm.tan(v)
        elif code == ASIN:
            r = dm.asin(v)
        elif code == ACOS:
            r = dm.acos(v)
        elif code == ATAN:
            r = dm.atan(v)
        elif code == EXP:
            r = dm.exp(v)
        elif code == LOG:
            r = dm.log(v)
        else:
            r = dm.tanh(v)
        out[i] = r


def _call(code: int, x):
    a = np.asarray(x, dtype=float)
    flat = np.ascontiguousarray(a).ravel()
    out = np.empty_like(flat)
    _apply(np.int64(code), flat, out)
    return float(out[0]) if a.ndim == 0 else out.reshape(a.shape)


def sin(x):
    """sin(x) (x in rad), the same bits everywhere (`detmath.sin`)."""
    return _call(SIN, x)


def cos(x):
    """cos(x) (x in rad), the same bits everywhere (`detmath.cos`)."""
    return _call(COS, x)


def tan(x):
    """tan(x) (x in rad), the same bits everywhere (`detmath.tan`)."""
    return _call(TAN, x)


def asin(x):
    """asin(x) (rad), the same bits everywhere (`detmath.asin`)."""
    return _call(ASIN, x)


def acos(x):
    """acos(x) (rad), the same bits everywhere (`detmath.acos`)."""
    return _call(ACOS, x)


def atan(x):
    """atan(x) (rad), the same bits everywhere (`detmath.atan`)."""
    return _call(ATAN, x)


def exp(x):
    """exp(x), the same bits everywhere (`detmath.exp`)."""
    return _call(EXP, x)


def log(x):
    """Natural logarithm, the same bits everywhere (`detmath.log`)."""
    return _call(LOG, x)


def tanh(x):
    """tanh(x), the same bits everywhere (`detmath.tanh`)."""
    return _call(TANH, x)


@jit_entry
def _row_sums(a, out):
    """out[i] = a[i, 0] + a[i, 1] + ..., left to right."""
    for i in range(a.shape[0]):
        s = 0.0
        for j in range(a.shape[1]):
            s += a[i, j]
        out[i] = s


def row_sum(a) -> np.ndarray | float:
    """Sum over the last axis, left to right (numpy's pairwise sum takes its order from
    the SIMD width it was dispatched for); a 1-D array gives a float."""
    a = np.asarray(a, dtype=float)
    flat = np.ascontiguousarray(a.reshape(-1, a.shape[-1]))
    out = np.empty(flat.shape[0])
    _row_sums(flat, out)
    return float(out[0]) if a.ndim == 1 else out.reshape(a.shape[:-1])


def trapezoid(y, x) -> float:
    """Trapezoidal integral of samples ``y`` at points ``x``, summed left to right."""
    y, x = np.asarray(y, dtype=float), np.asarray(x, dtype=float)
    return row_sum(0.5 * (y[1:] + y[:-1]) * (x[1:] - x[:-1]))

