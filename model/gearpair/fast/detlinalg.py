"""Small dense linear algebra with a fixed operation order (compiled): the same bits on every
x86-64 CPU.

numpy's ``@``, ``np.linalg.solve`` and scipy's ``eigh``, ``eig``, ``null_space`` and
``CubicSpline`` call BLAS/LAPACK kernels chosen by CPU (OpenBLAS's core type), whose
blocking, vector width and FMA use change the last bits of the model's set-up. Here every
result is written out as plain loops compiled without fast-math (no reassociation, no FMA
contraction; `gearpair.jitcache`), using only IEEE ``+ - * /``, ``sqrt`` and comparisons, so
the order of every rounding is fixed by this text and the bits are the same on every x86-64
machine (SSE2 arithmetic is IEEE double; a process that turns on flush-to-zero would change
results with subnormal intermediates, which the model's matrices do not produce).

The matrices are small (at most 6x6; tridiagonal systems of a few thousand rows for the
splines), so the classic unblocked algorithms are used:

- `matmul_into`, `matvec_into`, `outer_into`: each sum in ascending index order from 0.0;
- `solve_into`, `solve_many_into`: Gaussian elimination with partial pivoting (the first of
  equal candidates), flagging an exact zero pivot;
- `cholesky_into`: A = L L^T (lower triangle of A read);
- `eigh_generalized_into`: K v = lam M v, K symmetric, M symmetric positive definite:
  Cholesky M = L L^T, C = L^-1 K L^-T, cyclic Jacobi (row-cyclic order, the classic
  thresholds: sweeps 1-3 skip elements below 0.2 sum|offdiag| / n^2, from sweep 5 on an
  element negligible beside both diagonal entries is set to zero; done when the off-diagonal
  part is exactly zero, at most `MAX_SWEEPS` sweeps); eigenvalues ascending, V = L^-T W
  M-orthonormal (V^T M V = I) like scipy's eigh;
- `eig_real_general_into`: K v = lam M v, general, real eigenvalues expected: A = M^-1 K
  by `solve_many_into`, power-of-two balancing, Householder reduction to Hessenberg form,
  Francis double-shift QR (EISPACK hqr, at most `MAX_QR_ITS` iterations per eigenvalue), then
  each eigenvector by three steps of inverse iteration on the balanced matrix; a complex
  pair is flagged (`COMPLEX`) with its real and imaginary parts;
- `null_space_row_into`: an orthonormal basis of {x : w . x = 0} from one Householder
  reflector about the largest |w_k|;
- `cubic_spline_into`: scipy's ``CubicSpline(x, y)`` (not-a-knot ends) with the same
  equations for the slopes, solved by the Thomas algorithm (no pivoting) in a fixed order.

Sign conventions: every eigenvector and null-space basis vector has its largest-magnitude
component (the first of equal ones) positive; `eigh_generalized_into` normalizes to
v^T M v = 1, `eig_real_general_into` to unit Euclidean norm.

Each kernel (``*_into``) is an internal compiled function (`jit`: callable from compiled
code only), takes its outputs and scratch arrays (numba's runtime is off, so nothing
allocates: `work_shape` gives the scratch sizes) and returns a status code (`OK`, ...): the
engine's compiled code neither raises nor prints. Each has a cached entry point
(``*_entry``, `jit_entry`) with the same arguments for Python, and a Python function without
the suffix (`matmul`, `solve`, `eigh_generalized`, ...) allocates, checks and raises
`numpy.linalg.LinAlgError` (`ArithmeticError` for complex eigenvalues) as numpy/scipy would.
"""

from __future__ import annotations

import math

import numpy as np

from ..jitcache import jit, jit_entry, jit_hot

# -- status codes -----------------------------------------------------------------------------
OK = 0
SINGULAR = 1        # a zero pivot (solve), a zero row (null space), equal knots (spline)
NOT_POSITIVE = 2    # cholesky / eigh: M not positive definite
NO_CONVERGENCE = 3  # Jacobi sweeps or QR iterations exhausted
COMPLEX = 4         # eig_real_general: a complex pair of eigenvalues
NONFINITE = 5       # an input or a result is inf or nan
BAD_SHAPE = 6       # array shapes do not fit together (or are too small)
STATUS_TEXT = ("ok", "singular matrix", "matrix not positive definite",
               "no convergence", "complex eigenvalues", "non-finite value", "bad shapes")

MAX_SWEEPS = 50     # Jacobi sweeps (a 6x6 model matrix takes 5-7)
MAX_QR_ITS = 30     # Francis QR iterations per eigenvalue (exceptional shifts at 10 and 20)
N_INVIT = 3         # inverse-iteration steps per eigenvector
EPS = 2.220446049250313e-16


# -- helpers ----------------------------------------------------------------------------------
@jit_hot
def _finite2(A, m, n):
    for i in range(m):
        for j in range(n):
            if not math.isfinite(A[i, j]):
                return False
    return True


@jit_hot
def _finite1(x, n):
    for i in range(n):
        if not math.isfinite(x[i]):
            return False
    return True


@jit_hot
def _sign_of_largest_col(V, n, j):
    """-1.0 if the largest-magnitude entry of column j of V[:n] (the first of equal ones) is
    negative, else 1.0."""
    k = 0
    best = abs(V[0, j])
    for i in range(1, n):
        if abs(V[i, j]) > best:
            best = abs(V[i, j])
            k = i
    return -1.0 if V[k, j] < 0.0 else 1.0


# -- products ---------------------------------------------------------------------------------
@jit
def matmul_into(A, B, out):
    """out = A B (out must not overlap A or B); each entry summed over k = 0, 1, ... from
    0.0. Returns OK or BAD_SHAPE."""
    m, p = A.shape
    if B.shape[0] != p or out.shape[0] != m or out.shape[1] != B.shape[1]:
        return BAD_SHAPE
    n = B.shape[1]
    for i in range(m):
        for j in range(n):
            acc = 0.0
            for k in range(p):
                acc += A[i, k] * B[k, j]
            out[i, j] = acc
    return OK


@jit
def matvec_into(A, x, out):
    """out = A x (out must not overlap x), summed in ascending order. OK or BAD_SHAPE."""
    m, p = A.shape
    if x.shape[0] != p or out.shape[0] != m:
        return BAD_SHAPE
    for i in range(m):
        acc = 0.0
        for k in range(p):
            acc += A[i, k] * x[k]
        out[i] = acc
    return OK


@jit
def outer_into(u, v, out):
    """out = u v^T. OK or BAD_SHAPE."""
    m, n = u.shape[0], v.shape[0]
    if out.shape[0] != m or out.shape[1] != n:
        return BAD_SHAPE
    for i in range(m):
        for j in range(n):
            out[i, j] = u[i] * v[j]
    return OK


# -- linear systems ---------------------------------------------------------------------------
@jit
def gauss_aug(W, n, m, tiny):
    """Solve W[:n, :n] X = W[:n, n:n+m] in place by Gaussian elimination with partial pivoting
    (the first of equal candidates; whole rows swapped), X left in W[:n, n:n+m].

    A pivot of magnitude zero (``tiny`` = 0) makes it return SINGULAR; with ``tiny`` > 0 a
    pivot smaller than ``tiny`` is replaced by ``tiny`` with its sign (inverse iteration).
    """
    for c in range(n):
        p = c
        best = abs(W[c, c])
        for r in range(c + 1, n):
            if abs(W[r, c]) > best:
                best = abs(W[r, c])
                p = r
        if p != c:
            for k in range(c, n + m):
                tmp = W[c, k]
                W[c, k] = W[p, k]
                W[p, k] = tmp
        if best < tiny:
            W[c, c] = -tiny if W[c, c] < 0.0 else tiny
        elif best == 0.0:
            return SINGULAR
        piv = W[c, c]
        for r in range(c + 1, n):
            f = W[r, c] / piv
            W[r, c] = 0.0
            if f != 0.0:
                for k in range(c + 1, n + m):
                    W[r, k] -= f * W[c, k]
    for r in range(n - 1, -1, -1):
        for k in range(n, n + m):
            acc = W[r, k]
            for c in range(r + 1, n):
                acc -= W[r, c] * W[c, k]
            W[r, k] = acc / W[r, r]
    return OK


@jit
def solve_many_into(A, B, X, W):
    """X = A^-1 B (A: n x n, B and X: n x m; W: scratch, at least n x (n + m)). Returns OK,
    SINGULAR (an exact zero pivot), NONFINITE (in the input or the solution) or BAD_SHAPE."""
    n = A.shape[0]
    m = B.shape[1]
    if (A.shape[1] != n or B.shape[0] != n or X.shape[0] != n or X.shape[1] != m
            or W.shape[0] < n or W.shape[1] < n + m):
        return BAD_SHAPE
    if not (_finite2(A, n, n) and _finite2(B, n, m)):
        return NONFINITE
    for i in range(n):
        for j in range(n):
            W[i, j] = A[i, j]
        for j in range(m):
            W[i, n + j] = B[i, j]
    st = gauss_aug(W, n, m, 0.0)
    if st != OK:
        return st
    for i in range(n):
        for j in range(m):
            X[i, j] = W[i, n + j]
    return OK if _finite2(X, n, m) else NONFINITE


@jit
def solve_into(A, b, x, W):
    """x = A^-1 b (W: scratch, at least n x (n + 1)); status as `solve_many_into`."""
    n = A.shape[0]
    if (A.shape[1] != n or b.shape[0] != n or x.shape[0] != n
            or W.shape[0] < n or W.shape[1] < n + 1):
        return BAD_SHAPE
    if not (_finite2(A, n, n) and _finite1(b, n)):
        return NONFINITE
    for i in range(n):
        for j in range(n):
            W[i, j] = A[i, j]
        W[i, n] = b[i]
    st = gauss_aug(W, n, 1, 0.0)
    if st != OK:
        return st
    for i in range(n):
        x[i] = W[i, n]
    return OK if _finite1(x, n) else NONFINITE


@jit
def cholesky_into(A, L):
    """A = L L^T, L lower triangular (zeros above), from the lower triangle of A. Returns OK,
    NOT_POSITIVE (a pivot <= 0), NONFINITE or BAD_SHAPE."""
    n = A.shape[0]
    if A.shape[1] != n or L.shape[0] != n or L.shape[1] != n:
        return BAD_SHAPE
    if not _finite2(A, n, n):
        return NONFINITE
    for j in range(n):
        acc = A[j, j]
        for k in range(j):
            acc -= L[j, k] * L[j, k]
        if not (acc > 0.0):
            return NOT_POSITIVE
        ljj = math.sqrt(acc)
        L[j, j] = ljj
        for i in range(j):
            L[i, j] = 0.0
        for i in range(j + 1, n):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / ljj
    return OK


@jit_hot
def _forward(L, B, n):
    """B[:n, :n] <- L^-1 B (L lower triangular), column by column."""
    for c in range(n):
        for i in range(n):
            acc = B[i, c]
            for k in range(i):
                acc -= L[i, k] * B[k, c]
            B[i, c] = acc / L[i, i]


@jit_hot
def _backward_t(L, B, n):
    """B[:n, :n] <- L^-T B (L lower triangular), column by column."""
    for c in range(n):
        for i in range(n - 1, -1, -1):
            acc = B[i, c]
            for k in range(i + 1, n):
                acc -= L[k, i] * B[k, c]
            B[i, c] = acc / L[i, i]


# -- symmetric generalized eigenproblem -------------------------------------------------------
@jit_hot
def _rot(a, i1, j1, i2, j2, s, tau):
    g = a[i1, j1]
    h = a[i2, j2]
    a[i1, j1] = g - s * (h + g * tau)
    a[i2, j2] = h + s * (g - h * tau)


@jit
def jacobi_eigen(A, n, d, b, z, V):
    """Eigenvalues d[:n] and orthonormal eigenvectors (columns of V[:n, :n]) of the symmetric
    A[:n, :n] (upper triangle read; destroyed) by the cyclic Jacobi method (Rutishauser's
    form, as in Numerical Recipes' jacobi); b, z: scratch vectors. Unsorted. Returns OK or
    NO_CONVERGENCE."""
    for i in range(n):
        for j in range(n):
            V[i, j] = 0.0
        V[i, i] = 1.0
        b[i] = A[i, i]
        d[i] = A[i, i]
        z[i] = 0.0
    for sweep in range(MAX_SWEEPS):
        sm = 0.0
        for p in range(n - 1):
            for q in range(p + 1, n):
                sm += abs(A[p, q])
        if sm == 0.0:
            return OK
        tresh = 0.2 * sm / (n * n) if sweep < 3 else 0.0
        for p in range(n - 1):
            for q in range(p + 1, n):
                apq = A[p, q]
                g = 100.0 * abs(apq)
                if sweep > 3 and abs(d[p]) + g == abs(d[p]) and abs(d[q]) + g == abs(d[q]):
                    A[p, q] = 0.0
                elif abs(apq) > tresh:
                    h = d[q] - d[p]
                    if abs(h) + g == abs(h):
                        t = apq / h
                    else:
                        theta = 0.5 * h / apq
                        t = 1.0 / (abs(theta) + math.sqrt(1.0 + theta * theta))
                        if theta < 0.0:
                            t = -t
                    c = 1.0 / math.sqrt(1.0 + t * t)
                    s = t * c
                    tau = s / (1.0 + c)
                    h = t * apq
                    z[p] -= h
                    z[q] += h
                    d[p] -= h
                    d[q] += h
                    A[p, q] = 0.0
                    for j in range(p):
                        _rot(A, j, p, j, q, s, tau)
                    for j in range(p + 1, q):
                        _rot(A, p, j, j, q, s, tau)
                    for j in range(q + 1, n):
                        _rot(A, p, j, q, j, s, tau)
                    for j in range(n):
                        _rot(V, j, p, j, q, s, tau)
        for p in range(n):
            b[p] += z[p]
            d[p] = b[p]
            z[p] = 0.0
    return NO_CONVERGENCE


@jit_hot
def _sort_pairs(lam, V, n):
    """Sort lam[:n] ascending with the columns of V[:n, :n] (insertion sort: stable)."""
    for i in range(1, n):
        j = i
        while j > 0 and lam[j - 1] > lam[j]:
            tmp = lam[j]
            lam[j] = lam[j - 1]
            lam[j - 1] = tmp
            for r in range(n):
                tmp = V[r, j]
                V[r, j] = V[r, j - 1]
                V[r, j - 1] = tmp
            j -= 1


@jit
def eigh_generalized_into(K, M, lam, V, W):
    """K v = lam M v for symmetric K and symmetric positive definite M (n x n, lower triangles
    read): eigenvalues ascending into lam, eigenvectors into the columns of V with
    V^T M V = I, each with its largest-magnitude component positive. W: scratch, at least
    (2n + 3) x n. Returns OK, NOT_POSITIVE (M), NO_CONVERGENCE, NONFINITE or BAD_SHAPE."""
    n = K.shape[0]
    if (K.shape[1] != n or M.shape[0] != n or M.shape[1] != n or lam.shape[0] != n
            or V.shape[0] != n or V.shape[1] != n or W.shape[0] < 2 * n + 3
            or W.shape[1] < n):
        return BAD_SHAPE
    if not _finite2(K, n, n):
        return NONFINITE
    L = W[:n, :n]
    C = W[n:2 * n, :n]
    st = cholesky_into(M, L)
    if st != OK:
        return st
    for i in range(n):  # C = K from its lower triangle
        for j in range(i + 1):
            C[i, j] = K[i, j]
            C[j, i] = K[i, j]
    _forward(L, C, n)  # Y = L^-1 K
    for i in range(n):  # Y^T
        for j in range(i + 1, n):
            tmp = C[i, j]
            C[i, j] = C[j, i]
            C[j, i] = tmp
    _forward(L, C, n)  # L^-1 K L^-T, symmetric up to rounding: the lower triangle kept
    for i in range(n):
        for j in range(i + 1, n):
            C[i, j] = C[j, i]
    st = jacobi_eigen(C, n, lam, W[2 * n], W[2 * n + 1], V)
    if st != OK:
        return st
    _sort_pairs(lam, V, n)
    _backward_t(L, V, n)
    for j in range(n):
        sg = _sign_of_largest_col(V, n, j)
        if sg < 0.0:
            for i in range(n):
                V[i, j] = -V[i, j]
    return OK


# -- general real eigenproblem ----------------------------------------------------------------
@jit
def balance_n(X, n, d):
    """X[:n, :n] <- D^-1 X D with D = diag(d), powers of two (LAPACK gebal without
    permutations; exact)."""
    for i in range(n):
        d[i] = 1.0
    for _sweep in range(30):
        done = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(X[j, i])
                    r += abs(X[i, j])
            if c == 0.0 or r == 0.0:
                continue
            s0 = c + r
            f = 1.0
            while c < 0.5 * r:
                c *= 2.0
                r *= 0.5
                f *= 2.0
            while c >= 2.0 * r:
                c *= 0.5
                r *= 2.0
                f *= 0.5
            if c + r < 0.95 * s0:
                done = False
                d[i] *= f
                for j in range(n):
                    X[i, j] /= f
                    X[j, i] *= f
        if done:
            break


@jit
def hessenberg_1(a, n, u):
    """a[1:n+1, 1:n+1] (1-based) <- its upper Hessenberg form by Householder similarity
    transformations (columns 1 .. n-2 in order); u: a scratch vector of length n + 1."""
    for k in range(1, n - 1):
        scale = 0.0
        for i in range(k + 1, n + 1):
            scale += abs(a[i, k])
        if scale == 0.0:
            continue
        sigma = 0.0
        for i in range(k + 1, n + 1):
            u[i] = a[i, k] / scale
            sigma += u[i] * u[i]
        alpha = math.sqrt(sigma)
        x1 = u[k + 1]
        if x1 > 0.0:
            alpha = -alpha
        u[k + 1] = x1 - alpha
        h = sigma - x1 * alpha  # u^T u / 2
        for j in range(k + 1, n + 1):  # a <- (I - u u^T / h) a
            f = 0.0
            for i in range(k + 1, n + 1):
                f += u[i] * a[i, j]
            f /= h
            for i in range(k + 1, n + 1):
                a[i, j] -= f * u[i]
        for i in range(1, n + 1):  # a <- a (I - u u^T / h)
            f = 0.0
            for j in range(k + 1, n + 1):
                f += a[i, j] * u[j]
            f /= h
            for j in range(k + 1, n + 1):
                a[i, j] -= f * u[j]
        a[k + 1, k] = alpha * scale
        for i in range(k + 2, n + 1):
            a[i, k] = 0.0


@jit_hot
def _sign(a, b):
    return abs(a) if b >= 0.0 else -abs(a)


@jit_hot
def _small_subdiagonal(a, nn, anorm):
    """The largest lo <= nn whose subdiagonal a[lo, lo-1] is negligible against its
    neighbours' diagonal (set to zero), or 1: the active block is a[lo:nn+1, lo:nn+1]."""
    lo = nn
    while lo >= 2:
        s = abs(a[lo - 1, lo - 1]) + abs(a[lo, lo])
        if s == 0.0:
            s = anorm
        if abs(a[lo, lo - 1]) + s == s:
            a[lo, lo - 1] = 0.0
            break
        lo -= 1
    return lo


@jit_hot
def _deflate_pair(a, nn, t, wr, wi):
    """The two eigenvalues of the trailing 2 x 2 block a[nn-1:nn+1, nn-1:nn+1] plus shift t."""
    x, y = a[nn, nn], a[nn - 1, nn - 1]
    w = a[nn, nn - 1] * a[nn - 1, nn]
    p = 0.5 * (y - x)
    q = p * p + w
    z = math.sqrt(abs(q))
    x += t
    wi[nn - 1] = 0.0
    wi[nn] = 0.0
    if q >= 0.0:  # real pair
        z = p + _sign(z, p)
        wr[nn - 1] = x + z
        wr[nn] = x + z
        if z != 0.0:
            wr[nn] = x - w / z
    else:  # complex pair
        wr[nn - 1] = x + p
        wr[nn] = x + p
        wi[nn - 1] = -z
        wi[nn] = z


@jit_hot
def _double_shift_start(a, lo, nn, x, y, w):
    """Where the double-shift sweep starts (m) and the first column (p, q, r) of the shifted
    product: the lowest m >= lo at which two consecutive subdiagonals are small enough."""
    m = nn - 2
    p = q = r = 0.0
    while m >= lo:
        z = a[m, m]
        r = x - z
        s = y - z
        p = (r * s - w) / a[m + 1, m] + a[m, m + 1]
        q = a[m + 1, m + 1] - z - r - s
        r = a[m + 2, m + 1]
        s = abs(p) + abs(q) + abs(r)
        p /= s
        q /= s
        r /= s
        if m == lo:
            break
        u = abs(a[m, m - 1]) * (abs(q) + abs(r))
        v = abs(p) * (abs(a[m - 1, m - 1]) + abs(z) + abs(a[m + 1, m + 1]))
        if u + v == v:
            break
        m -= 1
    return m, p, q, r


@jit_hot
def _reflect(a, k, lo, nn, p, q, r, s):
    """Apply the Householder reflector of column k, (p, q, r) with norm s, from the left to
    rows k..k+2 and from the right to columns k..k+2 of the active block."""
    p += s
    x, y, z = p / s, q / s, r / s
    q /= p
    r /= p
    for j in range(k, nn + 1):
        v = a[k, j] + q * a[k + 1, j]
        if k != nn - 1:
            v += r * a[k + 2, j]
            a[k + 2, j] -= v * z
        a[k + 1, j] -= v * y
        a[k, j] -= v * x
    last = nn if nn < k + 3 else k + 3
    for i in range(lo, last + 1):
        v = x * a[i, k] + y * a[i, k + 1]
        if k != nn - 1:
            v += z * a[i, k + 2]
            a[i, k + 2] -= v * r
        a[i, k + 1] -= v * q
        a[i, k] -= v


@jit_hot
def _double_shift_sweep(a, lo, m, nn, p, q, r):
    """One Francis double-shift QR sweep over rows m..nn: chase the bulge down with
    3 x 3 Householder reflectors."""
    for i in range(m + 2, nn + 1):
        a[i, i - 2] = 0.0
        if i != m + 2:
            a[i, i - 3] = 0.0
    for k in range(m, nn):
        x = 0.0
        if k != m:
            p, q = a[k, k - 1], a[k + 1, k - 1]
            r = a[k + 2, k - 1] if k != nn - 1 else 0.0
            x = abs(p) + abs(q) + abs(r)
            if x != 0.0:
                p /= x
                q /= x
                r /= x
        s = _sign(math.sqrt(p * p + q * q + r * r), p)
        if s == 0.0:
            continue
        if k == m:
            if lo != m:
                a[k, k - 1] = -a[k, k - 1]
        else:
            a[k, k - 1] = -s * x
        _reflect(a, k, lo, nn, p, q, r, s)


@jit
def hqr_1(a, n, wr, wi):
    """Eigenvalues (wr + i wi, 1-based) of the upper Hessenberg a[1:n+1, 1:n+1] (destroyed)
    by Francis double-shift QR with deflation (the classical EISPACK hqr scheme: exceptional
    shifts after 10 and 20 iterations). Returns OK or NO_CONVERGENCE."""
    anorm = 0.0
    for i in range(1, n + 1):
        for j in range(max(i - 1, 1), n + 1):
            anorm += abs(a[i, j])
    nn, t, its = n, 0.0, 0
    while nn >= 1:
        lo = _small_subdiagonal(a, nn, anorm)
        if lo == nn:  # one root found
            wr[nn] = a[nn, nn] + t
            wi[nn] = 0.0
            nn -= 1
            its = 0
        elif lo == nn - 1:  # two roots found
            _deflate_pair(a, nn, t, wr, wi)
            nn -= 2
            its = 0
        else:
            if its == MAX_QR_ITS:
                return NO_CONVERGENCE
            x, y = a[nn, nn], a[nn - 1, nn - 1]
            w = a[nn, nn - 1] * a[nn - 1, nn]
            if its == 10 or its == 20:  # exceptional shift
                t += x
                for i in range(1, nn + 1):
                    a[i, i] -= x
                s = abs(a[nn, nn - 1]) + abs(a[nn - 1, nn - 2])
                x = 0.75 * s
                y = x
                w = -0.4375 * s * s
            its += 1
            m, p, q, r = _double_shift_start(a, lo, nn, x, y, w)
            _double_shift_sweep(a, lo, m, nn, p, q, r)
    return OK


@jit
def inverse_iteration(B, n, lam, x, Wlu):
    """An eigenvector of B[:n, :n] for its (real) eigenvalue lam into x (unit norm, largest
    component positive): `N_INVIT` steps of (B - lam I) y = x from x = 1, pivots smaller
    than eps ||B||_inf replaced by that; Wlu: scratch, at least n x (n + 1)."""
    nrm = 0.0
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += abs(B[i, j])
        nrm = max(nrm, acc)
    tiny = EPS * nrm
    if not (tiny > 0.0):
        tiny = EPS
    for i in range(n):
        x[i] = 1.0
    for _ in range(N_INVIT):
        for i in range(n):
            for j in range(n):
                Wlu[i, j] = B[i, j]
            Wlu[i, i] -= lam
            Wlu[i, n] = x[i]
        gauss_aug(Wlu, n, 1, tiny)
        big = 0.0
        for i in range(n):
            big = max(big, abs(Wlu[i, n]))
        if not (big > 0.0) or not math.isfinite(big):
            return NONFINITE
        for i in range(n):
            x[i] = Wlu[i, n] / big
    ss = 0.0
    k = 0
    best = abs(x[0])
    for i in range(n):
        ss += x[i] * x[i]
        if abs(x[i]) > best:
            best = abs(x[i])
            k = i
    nv = math.sqrt(ss)
    if x[k] < 0.0:
        nv = -nv
    for i in range(n):
        x[i] /= nv
    return OK


@jit
def eig_real_general_into(K, M, lam, lam_imag, V, W):
    """K v = lam M v for a general K and an invertible M (n x n), real eigenvalues expected:
    eigenvalues ascending into lam (lam_imag zero), eigenvectors into the columns of V, each
    of unit Euclidean norm with its largest-magnitude component positive. W: scratch, at
    least (4n + 6) x max(2n, n + 1).

    Returns OK, SINGULAR (M), COMPLEX (a complex pair: lam and lam_imag hold the unsorted
    eigenvalues, V zero), NO_CONVERGENCE, NONFINITE or BAD_SHAPE.
    """
    n = K.shape[0]
    wid = max(2 * n, n + 1)
    if (K.shape[1] != n or M.shape[0] != n or M.shape[1] != n or lam.shape[0] != n
            or lam_imag.shape[0] != n or V.shape[0] != n or V.shape[1] != n
            or W.shape[0] < 4 * n + 6 or W.shape[1] < wid):
        return BAD_SHAPE
    if not (_finite2(K, n, n) and _finite2(M, n, n)):
        return NONFINITE
    aug = W[:n]
    B = W[n:2 * n]
    H = W[2 * n:3 * n + 1]
    LU = W[3 * n + 1:4 * n + 1]
    d, wr, wi, x = W[4 * n + 1], W[4 * n + 2], W[4 * n + 3], W[4 * n + 4]
    for i in range(n):  # A = M^-1 K
        for j in range(n):
            aug[i, j] = M[i, j]
            aug[i, n + j] = K[i, j]
    st = gauss_aug(aug, n, n, 0.0)
    if st != OK:
        return st
    for i in range(n):
        for j in range(n):
            B[i, j] = aug[i, n + j]
    if not _finite2(B, n, n):
        return NONFINITE
    balance_n(B, n, d)
    for i in range(n + 1):
        for j in range(n + 1):
            H[i, j] = 0.0
    for i in range(n):
        for j in range(n):
            H[i + 1, j + 1] = B[i, j]
    hessenberg_1(H, n, x)
    st = hqr_1(H, n, wr, wi)
    if st != OK:
        return st
    for i in range(n):
        for j in range(n):
            V[i, j] = 0.0
    complex_pair = False
    for i in range(n):
        lam[i] = wr[i + 1]
        lam_imag[i] = wi[i + 1]
        if wi[i + 1] != 0.0:
            complex_pair = True
    if complex_pair:
        return COMPLEX
    for i in range(1, n):  # ascending (insertion sort: stable)
        j = i
        while j > 0 and lam[j - 1] > lam[j]:
            tmp = lam[j]
            lam[j] = lam[j - 1]
            lam[j - 1] = tmp
            j -= 1
    for c in range(n):
        st = inverse_iteration(B, n, lam[c], x, LU)
        if st != OK:
            return st
        ss = 0.0  # undo the balancing: A (D x) = lam (D x)
        for i in range(n):
            V[i, c] = d[i] * x[i]
            ss += V[i, c] * V[i, c]
        nv = math.sqrt(ss)
        if _sign_of_largest_col(V, n, c) < 0.0:
            nv = -nv
        for i in range(n):
            V[i, c] /= nv
    return OK


# -- null space of a row ----------------------------------------------------------------------
@jit
def null_space_row_into(w, N):
    """Orthonormal basis of {x : w . x = 0} (w of length n >= 2) into the n - 1 columns of N:
    the columns j != k of the Householder reflector that maps w onto e_k, k the index of the
    largest |w_k| (the first of equal ones), in ascending j; each column's largest-magnitude
    component is made positive. Returns OK, SINGULAR (w = 0), NONFINITE or BAD_SHAPE."""
    n = w.shape[0]
    if n < 2 or N.shape[0] != n or N.shape[1] != n - 1:
        return BAD_SHAPE
    if not _finite1(w, n):
        return NONFINITE
    k = 0
    best = abs(w[0])
    for i in range(1, n):
        if abs(w[i]) > best:
            best = abs(w[i])
            k = i
    if best == 0.0:
        return SINGULAR
    ss = 0.0
    for i in range(n):
        xi = w[i] / best
        ss += xi * xi
    nrm = math.sqrt(ss)
    xk = w[k] / best  # +-1
    vk = xk + _sign(nrm, xk)  # v = x + sign(x_k) |x| e_k
    h = nrm * abs(vk)  # v^T v / 2
    col = 0
    for j in range(n):
        if j == k:
            continue
        vj = w[j] / best
        for i in range(n):
            vi = vk if i == k else w[i] / best
            N[i, col] = -(vi * vj) / h
        N[j, col] += 1.0
        if _sign_of_largest_col(N, n, col) < 0.0:
            for i in range(n):
                N[i, col] = -N[i, col]
        col += 1
    return OK


# -- tridiagonal systems and cubic splines ----------------------------------------------------
@jit
def tridiagonal_solve_into(sub, diag, sup, rhs, n):
    """Thomas algorithm without pivoting, in place: the system with sub-diagonal sub[1:n]
    (row i: sub[i] x[i-1]), diagonal diag[:n] and super-diagonal sup[:n-1] (row i: sup[i]
    x[i+1]); diag and rhs are overwritten, the solution left in rhs. Returns OK or SINGULAR
    (a zero pivot)."""
    if diag[0] == 0.0:
        return SINGULAR
    for i in range(1, n):
        f = sub[i] / diag[i - 1]
        diag[i] = diag[i] - f * sup[i - 1]
        rhs[i] = rhs[i] - f * rhs[i - 1]
        if diag[i] == 0.0:
            return SINGULAR
    rhs[n - 1] = rhs[n - 1] / diag[n - 1]
    for i in range(n - 2, -1, -1):
        rhs[i] = (rhs[i] - sup[i] * rhs[i + 1]) / diag[i]
    return OK


@jit
def cubic_spline_into(x, y, c, W):
    """The not-a-knot cubic spline through (x, y) (x strictly increasing, n >= 2 points), as
    scipy's ``CubicSpline(x, y).c[::-1].T``: row i holds c0 .. c3 of
    y = c0 + c1 d + c2 d^2 + c3 d^3 on x[i] <= x <= x[i+1], d = x - x[i]. The knot slopes
    solve scipy's equations (n = 2: the line; n = 3: the parabola; else its tridiagonal
    system with the not-a-knot end rows) by `tridiagonal_solve_into` (n = 3: `gauss_aug`).
    W: scratch, at least 4 x max(n, 4). Returns OK, SINGULAR (x not strictly increasing),
    NONFINITE or BAD_SHAPE."""
    n = x.shape[0]
    if (n < 2 or y.shape[0] != n or c.shape[0] != n - 1 or c.shape[1] != 4
            or W.shape[0] < 4 or W.shape[1] < max(n, 4)):
        return BAD_SHAPE
    if not (_finite1(x, n) and _finite1(y, n)):
        return NONFINITE
    for i in range(n - 1):
        if not (x[i + 1] > x[i]):
            return SINGULAR
    sub, dia, sup, s = W[0], W[1], W[2], W[3]
    if n == 2:
        slope = (y[1] - y[0]) / (x[1] - x[0])
        s[0] = slope
        s[1] = slope
    elif n == 3:
        dx0 = x[1] - x[0]
        dx1 = x[2] - x[1]
        sl0 = (y[1] - y[0]) / dx0
        sl1 = (y[2] - y[1]) / dx1
        A = W[:3]  # [[1, 1, 0 | 2 sl0], [dx1, 2 (dx0 + dx1), dx0 | rhs], [0, 1, 1 | 2 sl1]]
        A[0, 0], A[0, 1], A[0, 2], A[0, 3] = 1.0, 1.0, 0.0, 2.0 * sl0
        A[1, 0], A[1, 1], A[1, 2] = dx1, 2.0 * (dx0 + dx1), dx0
        A[1, 3] = 3.0 * (dx0 * sl1 + dx1 * sl0)
        A[2, 0], A[2, 1], A[2, 2], A[2, 3] = 0.0, 1.0, 1.0, 2.0 * sl1
        st = gauss_aug(A, n, n - 2, 0.0)  # (n, n - 2) = (3, 1), typed as solve_many's
        if st != OK:
            return st
        s0, s1, s2 = A[0, 3], A[1, 3], A[2, 3]
        s[0], s[1], s[2] = s0, s1, s2
    else:
        # row i (1 .. n-2): dx[i] s[i-1] + 2 (dx[i-1] + dx[i]) s[i] + dx[i-1] s[i+1]
        #                   = 3 (dx[i] slope[i-1] + dx[i-1] slope[i])
        for i in range(1, n - 1):
            dxm = x[i] - x[i - 1]
            dxp = x[i + 1] - x[i]
            sub[i] = dxp
            dia[i] = 2.0 * (dxm + dxp)
            sup[i] = dxm
            s[i] = 3.0 * (dxp * ((y[i] - y[i - 1]) / dxm) + dxm * ((y[i + 1] - y[i]) / dxp))
        dx0 = x[1] - x[0]
        dx1 = x[2] - x[1]
        d = x[2] - x[0]
        dia[0] = dx1
        sup[0] = d
        s[0] = (((dx0 + 2.0 * d) * dx1 * ((y[1] - y[0]) / dx0)
                 + dx0 * dx0 * ((y[2] - y[1]) / dx1)) / d)
        dxa = x[n - 1] - x[n - 2]  # dx[-1]
        dxb = x[n - 2] - x[n - 3]  # dx[-2]
        d = x[n - 1] - x[n - 3]
        dia[n - 1] = dxb
        sub[n - 1] = d
        s[n - 1] = ((dxa * dxa * ((y[n - 2] - y[n - 3]) / dxb)
                     + (2.0 * d + dxa) * dxb * ((y[n - 1] - y[n - 2]) / dxa)) / d)
        sub[0] = 0.0
        sup[n - 1] = 0.0
        st = tridiagonal_solve_into(sub, dia, sup, s, n)
        if st != OK:
            return st
    for i in range(n - 1):  # scipy's CubicHermiteSpline coefficients
        dx = x[i + 1] - x[i]
        slope = (y[i + 1] - y[i]) / dx
        t = (s[i] + s[i + 1] - 2.0 * slope) / dx
        c[i, 0] = y[i]
        c[i, 1] = s[i]
        c[i, 2] = (slope - s[i]) / dx - t
        c[i, 3] = t / dx
    return OK if _finite2(c, n - 1, c.shape[1]) else NONFINITE


# -- entry points (cached; called from Python) ------------------------------------------------
@jit_entry
def matmul_entry(A, B, out):
    return matmul_into(A, B, out)


@jit_entry
def matvec_entry(A, x, out):
    return matvec_into(A, x, out)


@jit_entry
def outer_entry(u, v, out):
    return outer_into(u, v, out)


@jit_entry
def solve_entry(A, b, x, W):
    return solve_into(A, b, x, W)


@jit_entry
def solve_many_entry(A, B, X, W):
    return solve_many_into(A, B, X, W)


@jit_entry
def cholesky_entry(A, L):
    return cholesky_into(A, L)


@jit_entry
def eigh_generalized_entry(K, M, lam, V, W):
    return eigh_generalized_into(K, M, lam, V, W)


@jit_entry
def eig_real_general_entry(K, M, lam, lam_imag, V, W):
    return eig_real_general_into(K, M, lam, lam_imag, V, W)


@jit_entry
def null_space_row_entry(w, N):
    return null_space_row_into(w, N)


@jit_entry
def cubic_spline_entry(x, y, c, W):
    return cubic_spline_into(x, y, c, W)


# -- Python functions -------------------------------------------------------------------------
def work_shape(kernel: str, n: int, m: int = 1) -> tuple[int, int]:
    """The scratch ``W`` a kernel needs for size n (``m``: right-hand sides of
    ``solve_many``): kernel one of "solve", "solve_many", "eigh_generalized",
    "eig_real_general", "cubic_spline"."""
    shapes = {"solve": (n, n + 1), "solve_many": (n, n + m),
              "eigh_generalized": (2 * n + 3, n),
              "eig_real_general": (4 * n + 6, max(2 * n, n + 1)),
              "cubic_spline": (4, max(n, 4))}
    return shapes[kernel]


def _f64(a, ndim: int, name: str) -> np.ndarray:
    out = np.ascontiguousarray(a, dtype=np.float64)
    if out.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got shape {out.shape}")
    return out


def _square(a, name: str) -> np.ndarray:
    out = _f64(a, 2, name)
    if out.shape[0] != out.shape[1] or out.shape[0] == 0:
        raise ValueError(f"{name} must be square, got shape {out.shape}")
    return out


def _check(status: int, what: str) -> None:
    if status == COMPLEX:
        raise ArithmeticError(f"{what}: complex eigenvalues")
    if status == BAD_SHAPE:
        raise ValueError(f"{what}: array shapes do not fit")
    if status != OK:
        raise np.linalg.LinAlgError(f"{what}: {STATUS_TEXT[status]}")


def matmul(A, B, out: np.ndarray | None = None) -> np.ndarray:
    """A B (2-D), in a fixed summation order."""
    A, B = _f64(A, 2, "A"), _f64(B, 2, "B")
    if A.shape[1] != B.shape[0]:
        raise ValueError(f"matmul: shapes {A.shape} and {B.shape} do not fit")
    if out is None:
        out = np.empty((A.shape[0], B.shape[1]))
    _check(matmul_entry(A, B, out), "matmul")
    return out


def matvec(A, x) -> np.ndarray:
    """A x, in a fixed summation order."""
    A, x = _f64(A, 2, "A"), _f64(x, 1, "x")
    out = np.empty(A.shape[0])
    _check(matvec_entry(A, x, out), "matvec")
    return out


def outer(u, v) -> np.ndarray:
    """u v^T."""
    u, v = _f64(u, 1, "u"), _f64(v, 1, "v")
    out = np.empty((u.shape[0], v.shape[0]))
    _check(outer_entry(u, v, out), "outer")
    return out


def solve(A, b) -> np.ndarray:
    """A^-1 b for b of shape (n,) or (n, m), as ``np.linalg.solve``; raises LinAlgError on
    an exact zero pivot."""
    A = _square(A, "A")
    n = A.shape[0]
    b = np.ascontiguousarray(b, dtype=np.float64)
    if b.ndim == 1:
        x = np.empty(n)
        _check(solve_entry(A, b, x, np.empty(work_shape("solve", n))), "solve")
        return x
    if b.ndim != 2:
        raise ValueError(f"b must be 1-D or 2-D, got shape {b.shape}")
    x = np.empty(b.shape)
    _check(solve_many_entry(A, b, x, np.empty(work_shape("solve_many", n, b.shape[1]))),
           "solve")
    return x


def cholesky(A) -> np.ndarray:
    """Lower L with A = L L^T (lower triangle of A read), as ``np.linalg.cholesky``."""
    A = _square(A, "A")
    L = np.empty_like(A)
    _check(cholesky_entry(A, L), "cholesky")
    return L


def eigh_generalized(K, M) -> tuple[np.ndarray, np.ndarray]:
    """(eigenvalues ascending, eigenvectors as columns with V^T M V = I, largest component
    positive) of K v = lam M v, as ``scipy.linalg.eigh(K, M)`` up to the vectors' signs."""
    K, M = _square(K, "K"), _square(M, "M")
    n = K.shape[0]
    lam, V = np.empty(n), np.empty((n, n))
    _check(eigh_generalized_entry(K, M, lam, V, np.empty(work_shape("eigh_generalized", n))),
           "eigh_generalized")
    return lam, V


def eig_real_general(K, M) -> tuple[np.ndarray, np.ndarray]:
    """(real eigenvalues ascending, eigenvectors as columns of unit norm, largest component
    positive) of K v = lam M v, as ``scipy.linalg.eig(K, M)`` sorted; ArithmeticError if a
    pair is complex."""
    K, M = _square(K, "K"), _square(M, "M")
    n = K.shape[0]
    lam, lam_imag, V = np.empty(n), np.empty(n), np.empty((n, n))
    st = eig_real_general_entry(K, M, lam, lam_imag, V,
                                np.empty(work_shape("eig_real_general", n)))
    if st == COMPLEX:
        raise ArithmeticError(f"eig_real_general: complex eigenvalues {lam + 1j * lam_imag}")
    _check(st, "eig_real_general")
    return lam, V


def null_space_row(w) -> np.ndarray:
    """An orthonormal basis (n x (n - 1)) of the null space of the row w, as
    ``scipy.linalg.null_space(w[None])`` up to a rotation within the null space."""
    w = _f64(w, 1, "w")
    N = np.empty((w.shape[0], max(w.shape[0] - 1, 0)))
    _check(null_space_row_entry(w, N), "null_space_row")
    return N


def cubic_spline_not_a_knot(x, y) -> np.ndarray:
    """Coefficients (n - 1, 4) of the not-a-knot cubic spline, as
    ``scipy.interpolate.CubicSpline(x, y).c[::-1].T``."""
    x, y = _f64(x, 1, "x"), _f64(y, 1, "y")
    n = x.shape[0]
    c = np.empty((max(n - 1, 0), 4))
    _check(cubic_spline_entry(x, y, c, np.empty(work_shape("cubic_spline", n))),
           "cubic_spline_not_a_knot")
    return c
