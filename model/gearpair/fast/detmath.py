"""Elementary functions that give the same bits on every machine, for the compiled engine.

Why: numba lowers ``math.exp``, ``x ** y``, ``math.tanh`` ... to calls into the C library,
and glibc picks the implementation of those by the CPU's features (its FMA/AVX2 variants
round differently in the last bit), so the same run gave different trajectories on two
x86-64 machines. The functions here are the project's own, compiled with the engine: they use
only IEEE-754 basic operations (+, -, *, /, sqrt, comparisons, floor, exact scaling by powers of
two and exact bit manipulation), all correctly rounded by definition, in round to nearest,
with no fused multiply-add (numba compiles with ``fastmath=False``, so LLVM neither
contracts ``a * b + c`` into an FMA nor reorders a sum; never write ``math.fma`` here), so
every machine computes the same bits, as Java's StrictMath does.

Accuracy: below 1 ulp everywhere, nearly correctly rounded: `tests/test_detmath.py`
measures at most 0.51 ulp against mpmath over 100,000 arguments per function. Every function
but exp forms its result as a double-double (an unevaluated sum hi + lo of about 106 bits,
built with error-free transformations: Knuth's two-sum and Dekker's product by Veltkamp
splitting) with a relative error of 2^-59 or less and rounds it once; exp (and the last
step of pow) rounds scale + scale * tmp, tmp < 2^-8, once (< 0.51 ulp). Special values follow
C99 Annex F (NaN, +-inf, +-0, overflow to inf, underflow to 0 or a subnormal, a domain error
gives NaN without raising; pow's special cases in full). Not correctly rounded in every
case (no function is proven so): a result can differ from the correctly rounded one when
the exact value lies within about 0.01 ulp of a midpoint between two doubles.

The algorithms:

- ``exp``: x = (128 k + j) ln2/128 + r, |r| <= ln2/256; exp(x) = 2^k 2^(j/128) (1 + p(r))
  with a 128-entry table of 2^(j/128) (value and relative tail) and the degree-5 Taylor
  polynomial p, the subnormal range rounded once (the glibc/ARM optimized-routines method).
  ``_exp_dd`` is the same reduction keeping the result as a double-double, for ``expm1``,
  ``sinh``, ``cosh`` and ``tanh``.
- ``log``: x = 2^k z, z in [0.6875, 1.375); log x = k ln2 - log(invc) + log1p(r) with
  r = z invc - 1 computed exactly (invc has 20 bits, z is split in 33 + 20 bits, so both
  products are exact), invc = 1 on the two intervals next to 1 (no cancellation near 1), a
  128-entry table of -log(invc) as double-doubles, and log1p(r) to r^10 (|r| < 2^-7).
- ``pow``: exp(y log|x|) with log|x| as a double-double (relative error < 2^-68), y log|x|
  as a double-double and exp's reduction taking the low part as a tail; C99's special
  cases (signs for negative x and integer y, zeros, infinities, 1^y = x^0 = 1) first.
- ``expm1``, ``log1p``: from the double-double exp and log (exp(x) - 1 and log(u) + the
  rounding error of u = 1 + x over u), the tiny arguments returned as they are.
- ``sinh``, ``cosh``, ``tanh``: (E -+ 1/E)/2 and (E^2 - 1)/(E^2 + 1) in double-doubles from
  E = exp(|x|) (double-double); exp(|x|)/2 scaled by a power of two past |x| = 21.
- ``sin``, ``cos``, ``tan``: reduction to y = x - n pi/2, |y| <= pi/4, as a double-double:
  none for |x| <= pi/4; Cody-Waite with pi/2 in four parts (32 + 32 + 32 + 53 bits, exact
  products n * part for n < 2^20) for |x| < 2^20 pi/2; beyond, Payne-Hanek: x (four 24-bit
  pieces) times the bits of 2/pi that matter (a table of 24-bit pieces), summed exactly
  modulo 4. Then the odd polynomial x - x^3/6 + x^5 Q(x^2) (error < 2^-64 on [0, pi/4],
  the x^3 term in double-double) and the even 1 - x^2/2 + x^4/24 + x^6 R(x^2) (< 2^-66,
  the first three terms in double-double);
  tan = sin/cos (or -cos/sin) divided as double-doubles.
- ``atan``, ``atan2``, ``asin``, ``acos``: atan(t) for t in [0, 1] as atan(c) + atan(u),
  c = j/16 the nearest sixteenth, u = (t - c)/(1 + t c) (|u| <= 1/32) in double-double, a
  table of atan(j/16) and the odd Taylor polynomial to u^13; t > 1 through pi/2 - atan(1/t);
  atan2 scales both arguments by a power of two and divides as double-doubles;
  asin x = atan(x / sqrt(1 - x^2)) and acos x = atan(sqrt(1 - x^2) / x) (plus pi for
  x < 0), with 1 - x^2 and its square root as double-doubles.

The tables (2^(j/128), log(invc), atan(j/16), the bits of 2/pi) are computed at import from
exact integer arithmetic (series and integer square roots with 136 or more bits, then Python's
correctly rounded int-to-float conversion), so they are the same on every machine and need
no 700 hand-copied literals; `tests/test_detmath.py` checks them against mpmath.

Every public function is `jit_hot` (inlined into its compiled callers, which alone may call
it) and takes and returns float64.
"""

from __future__ import annotations

import math
import struct

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from ..jitcache import jit_hot

__all__ = ["acos", "asin", "atan", "atan2", "cos", "cosh", "exp", "expm1", "log", "log1p",
           "pow", "sin", "sinh", "tan", "tanh"]


# -- bit access -------------------------------------------------------------------------------
@intrinsic
def _bits(typingctx, x):
    """The bit pattern of a float64 as an int64: an LLVM bitcast (no memory, no array)."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(context.cast(builder, args[0], x, types.float64),
                               ir.IntType(64))

    return types.int64(x), codegen


@intrinsic
def _float(typingctx, i):
    """The float64 whose bit pattern is the int64 ``i`` (an LLVM bitcast)."""
    if not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(context.cast(builder, args[0], i, types.int64), ir.DoubleType())

    return types.float64(i), codegen


def _bits_py(x: float) -> int:
    return struct.unpack("<q", struct.pack("<d", x))[0]


_h = float.fromhex
# -- constants (each split so that the products the code forms with it are exact) -------------
SHIFT = _h("0x1.8p52")  # x + SHIFT rounds x to an integer held in the low bits
SHIFT_BITS = _bits_py(SHIFT)
INV_LN2N = _h("0x1.71547652b82fep+7")  # 128/ln2
LN2HI_N = _h("0x1.62e42fee00000p-8")  # ln2/128, 32 bits: k * LN2HI_N exact for |k| < 2^21
LN2LO_N = _h("0x1.a39ef35793c76p-40")  # ln2/128 - LN2HI_N
LN2_HI = _h("0x1.62e42fefa3800p-1")  # ln2, 42 bits: k * LN2_HI exact for |k| < 2^11
LN2_LO = _h("0x1.ef35793c76730p-45")
PIO2_H = _h("0x1.921fb54442d18p+0")  # pi/2 = PIO2_H + PIO2_L
PIO2_L = _h("0x1.1a62633145c07p-54")
PI_H = _h("0x1.921fb54442d18p+1")
PI_L = _h("0x1.1a62633145c07p-53")
PIO4_H = _h("0x1.921fb54442d18p-1")  # pi/4 and 3pi/4 rounded (atan2's infinities)
PI3O4_H = _h("0x1.2d97c7f3321d2p+1")
INVPIO2 = _h("0x1.45f306dc9c883p-1")  # 2/pi
PIO2_1 = _h("0x1.921fb54400000p+0")  # pi/2 in four parts, the first three of 32 bits:
PIO2_2 = _h("0x1.0b4611a600000p-34")  # n * PIO2_k exact for |n| <= 2^20
PIO2_3 = _h("0x1.3198a2e000000p-69")
PIO2_4 = _h("0x1.b839a252049c1p-104")
MEDIUM = 1647099.0  # < 2^20 pi/2: the Cody-Waite reduction's range
TWO_M1022 = _h("0x1p-1022")
TWO_P1009 = _h("0x1p1009")
TWO_P54 = _h("0x1p54")
TWO_M9 = _h("0x1p-9")
TWO_M24 = _h("0x1p-24")
TWO_M26 = _h("0x1p-26")
TWO_M27 = _h("0x1p-27")
TWO_M28 = _h("0x1p-28")
TWO_M54 = _h("0x1p-54")
TWO_M57 = _h("0x1p-57")
TWO_P52 = _h("0x1p52")
TWO_P60 = _h("0x1p60")
MANT_MASK = (1 << 52) - 1
# Taylor coefficients (exp, log1p, atan): correctly rounded quotients
C3, C4, C5, C6 = 1.0 / 6.0, 1.0 / 24.0, 1.0 / 120.0, 1.0 / 720.0
# sin x = x + x^3 S1 + x^5 Q(x^2) on |x| <= pi/4 (+0.002): S1 = -1/6 as a double-double,
# Q a Chebyshev fit (relative error of the whole < 2^-64)
S1_H = _h("-0x1.5555555555555p-3")
S1_L = _h("-0x1.5555555555555p-57")
SQ0, SQ1 = _h("0x1.1111111111111p-7"), _h("-0x1.a01a01a019ecep-13")
SQ2, SQ3 = _h("0x1.71de3a550abf1p-19"), _h("-0x1.ae64552f0d1eep-26")
SQ4, SQ5 = _h("0x1.612255f13a9a4p-33"), _h("-0x1.ab902e8be0a58p-41")
# cos x = 1 - x^2/2 + x^4 C24 + x^6 R(x^2) on |x| <= pi/4 (+0.002): C24 = 1/24 as a
# double-double, R a Chebyshev fit (error of the whole < 2^-66)
C24_H = _h("0x1.5555555555555p-5")
C24_L = _h("0x1.5555555555555p-59")
CR0, CR1 = _h("-0x1.6c16c16c16c17p-10"), _h("0x1.a01a01a019f86p-16")
CR2, CR3 = _h("-0x1.27e4fb775e836p-22"), _h("0x1.1eed8e6a05610p-29")
CR4, CR5 = _h("-0x1.93957931c17ddp-37"), _h("0x1.abe3680936065p-45")


# -- tables, from exact integer arithmetic at import --------------------------------------------
_FIX = 136  # fraction bits of the fixed-point values the tables are rounded from


def _atanh_fixed(p: int, q: int, bits: int) -> int:
    """atanh(p/q) * 2^bits (0 <= p < q), truncated: sum of (p/q)^(2i+1)/(2i+1)."""
    term = (p << bits) // q
    total, k, p2, q2 = term, 1, p * p, q * q
    while term:
        term = term * p2 // q2
        k += 2
        total += term // k
    return total


def _atan_fixed(p: int, q: int, bits: int) -> int:
    """atan(p/q) * 2^bits (0 <= p <= q) by Euler's series (terms fall by 2 at least):
    atan x = (y/x) sum 2^(2n) (n!)^2/(2n+1)! y^n, y = x^2/(1 + x^2)."""
    s = p * p + q * q
    term = (p * q << bits) // s
    total, n = term, 0
    while term:
        term = term * (2 * n + 2) * p * p // ((2 * n + 3) * s)
        total += term
        n += 1
    return total


def _pi_fixed(bits: int) -> int:
    """pi * 2^bits (Machin: 16 atan(1/5) - 4 atan(1/239)), the last few units uncertain."""
    def atan_inv(n: int, b: int) -> int:
        term = (1 << b) // n
        total, k, sign = term, 1, -1
        while term:
            term //= n * n
            k += 2
            total += sign * (term // k)
            sign = -sign
        return total

    g = bits + 16
    return (16 * atan_inv(5, g) - 4 * atan_inv(239, g)) >> 16


def _dd(v: int, bits: int) -> tuple[float, float]:
    """(hi, lo) with hi the double nearest v * 2^-bits and lo the double nearest the rest."""
    hi = v / (1 << bits)  # int / int: correctly rounded
    num, den = hi.as_integer_ratio()
    return hi, (v - (num << bits) // den) / (1 << bits)


def _exp_table():
    """2^(j/128), j < 128: the value, its relative tail (2^(j/128) = hi (1 + tail)), the bits
    of hi less j << 45 (adding (128 k + j) << 45 then scales by 2^k) and hi's Veltkamp split."""
    root = 1 << (128 * _FIX + 1)
    for _ in range(7):  # floor(2^(1/128) 2^_FIX): floor of sqrt of floor is floor of sqrt
        root = math.isqrt(root)
    t = 1 << _FIX
    hi, tail, sbits = np.empty(128), np.empty(128), np.empty(128, np.int64)
    for j in range(128):
        h = t / (1 << _FIX)
        num, den = h.as_integer_ratio()
        exact = (num << _FIX) // den
        hi[j], tail[j], sbits[j] = h, (t - exact) / exact, _bits_py(h) - (j << 45)
        t = (t * root) >> _FIX  # error below 2 units per step: < 2^-128 at j = 127
    return hi, tail, sbits


EXP_HI, EXP_TAIL, EXP_SBITS = _exp_table()
LOG_OFF = 0x3FE6000000000000  # z in [0x1.6p-1, 0x1.6p0): the 128 intervals of `_log_dd`


def _log_table():
    """invc (20 bits, 1/c rounded, c the interval's centre; 1 on the intervals [1 - 2^-8, 1)
    and [1, 1 + 2^-7)) and -log(invc) = hi + lo for each of the 128 intervals, hi rounded to
    a multiple of 2^-42 (as LN2_HI is: k LN2_HI + hi is exact), lo to a double."""
    invc, lh, ll = np.empty(128), np.empty(128), np.empty(128)
    for i in range(128):
        lo = struct.unpack("<d", struct.pack("<q", LOG_OFF + (i << 45)))[0]
        hi = struct.unpack("<d", struct.pack("<q", LOG_OFF + ((i + 1) << 45)))[0]
        cn, cd = ((lo + hi) / 2).as_integer_ratio()  # exact: few bits
        m = 1 << 19 if i in (79, 80) else ((cd << 20) + cn) // (2 * cn)  # round(2^19/c)
        invc[i] = m / (1 << 19)
        a = _atanh_fixed(abs(m - (1 << 19)), m + (1 << 19), _FIX)  # log(invc) = 2 atanh(.)
        v = -2 * a if m > 1 << 19 else 2 * a
        h = (v + (1 << (_FIX - 43))) >> (_FIX - 42)  # v 2^-_FIX to the nearest 2^-42
        lh[i], ll[i] = h / (1 << 42), (v - (h << (_FIX - 42))) / (1 << _FIX)
    return invc, lh, ll


LOG_INVC, LOG_C_H, LOG_C_L = _log_table()


def _atan_table():
    """atan(j/16), j = 0..16, as double-doubles."""
    h, lo = np.empty(17), np.empty(17)
    for j in range(17):
        h[j], lo[j] = _dd(_atan_fixed(j, 16, _FIX), _FIX)
    return h, lo


ATAN_H, ATAN_L = _atan_table()


def _two_over_pi_table(n: int = 60) -> np.ndarray:
    """The first 24 n bits of 2/pi in 24-bit pieces: 2/pi = sum G[i] 2^(-24 (i + 1))."""
    b = 24 * n + 64
    w = (1 << (2 * b + 9)) // _pi_fixed(b + 8)  # (2/pi) 2^b
    return np.array([float((w >> (b - 24 * (i + 1))) & 0xFFFFFF) for i in range(n)])


TWO_OVER_PI = _two_over_pi_table()


# -- error-free transformations and double-double arithmetic -----------------------------------
@jit_hot
def _two_sum(a, b):
    """(s, e) with s = fl(a + b) and s + e = a + b exactly (Knuth)."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@jit_hot
def _fast_two_sum(a, b):
    """`_two_sum` for |a| >= |b| (or a = 0): (s, e), s + e = a + b exactly (Dekker)."""
    s = a + b
    return s, b - (s - a)


@jit_hot
def _split(a):
    """a = h + l with h and l of 26 bits each (Veltkamp; |a| < 2^995)."""
    c = 134217729.0 * a  # 2^27 + 1
    h = c - (c - a)
    return h, a - h


@jit_hot
def _two_prod(a, b):
    """(p, e) with p = fl(a b) and p + e = a b exactly (Dekker's product, no FMA)."""
    p = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


@jit_hot
def _two_sqr(a):
    """`_two_prod` (a, a) with one split."""
    p = a * a
    ah, al = _split(a)
    return p, ((ah * ah - p) + 2.0 * ah * al) + al * al


@jit_hot
def _div_dd(ah, al, bh, bl):
    """(ah + al) / (bh + bl) as a normalized double-double (relative error ~2^-104); the
    first element is the quotient rounded to a double (within 0.5 ulp + 2^-50).

    One division: q = ah (1/bh) is within 2 ulps, and the correction (the exact residual
    ah - q bh, by Dekker's product, times 1/bh) restores what q lacks."""
    inv = 1.0 / bh
    q = ah * inv
    p, e = _two_prod(q, bh)
    return _fast_two_sum(q, (((ah - p) - e) + al - q * bl) * inv)


@jit_hot
def _pow2(k):
    """2^k for an integer k in [-1022, 1023], built from its bits."""
    return _float((k + 1023) << 52)


@jit_hot
def _scale(v, k):
    """v 2^k for |k| < 2044, in two exact steps while the result is normal (it overflows
    to inf as a single multiplication would)."""
    k1 = k >> 1
    return v * _pow2(k1) * _pow2(k - k1)


@jit_hot
def _ilogb(v):
    """floor(log2 v) for a finite v > 0, subnormals included."""
    e = (_bits(v) >> 52) & 0x7FF
    if e == 0:
        return ((_bits(v * TWO_P54) >> 52) & 0x7FF) - 1077
    return e - 1023


# -- exp, log, pow --------------------------------------------------------------------------------
@jit_hot
def _exp_special(tmp, sbits, m):
    """exp for 512 <= |x| < 1024: scale (2^k 2^(j/128), bits ``sbits``) times 1 + tmp,
    without overflow in the scale, and rounded once in the subnormal range (glibc's way)."""
    if m > 0:
        scale = _float(sbits - (1009 << 52))
        return TWO_P1009 * (scale + scale * tmp)
    scale = _float(sbits + (1022 << 52))
    y = scale + scale * tmp
    if y < 1.0:
        # round y to the bits a subnormal keeps before scaling: 1 + y rounds at 2^-52
        lo = scale - y + scale * tmp
        hi = 1.0 + y
        lo = 1.0 - hi + y + lo
        y = (hi + lo) - 1.0
    return TWO_M1022 * y


@jit_hot
def _exp_kernel(x, xtail):
    """exp(x + xtail), xtail a small correction (pow's low part; 0 for exp)."""
    top = (_bits(x) >> 52) & 0x7FF
    big = False
    if top < 969 or top >= 1032:  # |x| < 2^-54, or |x| >= 512, inf, nan
        if top < 969:
            return 1.0 + x
        if top >= 1033:  # |x| >= 1024
            return 0.0 if x < 0.0 else x + math.inf
        big = True
    kd = x * INV_LN2N + SHIFT
    m = _bits(kd) - SHIFT_BITS  # round(x 128/ln2) = 128 k + j
    kd -= SHIFT
    r = x - kd * LN2HI_N - kd * LN2LO_N + xtail
    j = m & 127
    sbits = EXP_SBITS[j] + (m << 45)
    r2 = r * r
    tmp = EXP_TAIL[j] + r + r2 * (0.5 + r * C3) + r2 * r2 * (C4 + r * C5)
    if big:
        return _exp_special(tmp, sbits, m)
    scale = _float(sbits)
    return scale + scale * tmp


@jit_hot
def exp(x):
    """e^x (within 0.51 ulp; inf past 709.782712893384, 0 below -745.1332191019412)."""
    return _exp_kernel(float(x), 0.0)


@jit_hot
def _exp_dd(x):
    """exp(x) = 2^k (hi + lo) for finite |x| < 1100, hi + lo in [0.99, 2.01] a normalized
    double-double with relative error < 2^-68. Returns (k, hi, lo)."""
    kd = x * INV_LN2N + SHIFT
    m = _bits(kd) - SHIFT_BITS
    kd -= SHIFT
    rh, rl = _two_sum(x - kd * LN2HI_N, -(kd * LN2LO_N))  # the first difference is exact
    j = m & 127
    th = EXP_HI[j]
    r2 = rh * rh
    pl = rl + r2 * (0.5 + rh * (C3 + rh * (C4 + rh * (C5 + rh * C6))))  # expm1(r) - rh
    ah, al = _two_prod(th, rh)
    eh, el = _fast_two_sum(th, ah)
    eh, el = _fast_two_sum(eh, el + (al + th * (pl + EXP_TAIL[j] * (1.0 + rh))))
    return m >> 7, eh, el


@jit_hot
def _log_dd(x):
    """log(x) for a finite x > 0 as a normalized double-double (relative error < 2^-68)."""
    ix = _bits(x)
    if ix < 0x0010000000000000:  # subnormal: normalize, the exponent kept in the bits
        ix = _bits(x * TWO_P52) - (52 << 52)
    tmp = ix - LOG_OFF
    i = (tmp >> 45) & 127
    k = tmp >> 52
    iz = ix - (tmp & (0xFFF << 52))
    z = _float(iz)
    zh = _float(iz & -(1 << 20))  # 33 bits: zh * invc is exact (20 bits)
    invc = LOG_INVC[i]
    rh, rl = _two_sum(zh * invc - 1.0, (z - zh) * invc)  # the difference is exact
    ph, pl = _two_sqr(rh)
    # r^3 (1/3 - r/4 + ... - r^7/10), in Estrin's order (a shorter chain than Horner's)
    p4 = ph * ph
    q = rh * ph * ((1.0 / 3.0 - 0.25 * rh) + ph * (0.2 - 1.0 / 6.0 * rh)
                   + p4 * ((1.0 / 7.0 - 0.125 * rh) + ph * (1.0 / 9.0 - 0.1 * rh)))
    kd = float(k)
    # k LN2_HI + LOG_C_H is exact (multiples of 2^-42 below 2^11); it is 0 or larger than
    # |rh| (|log c| > 2^-7.5 where c != 1, |rh| < 2^-7), so fast two-sums suffice
    s, e2 = _fast_two_sum(kd * LN2_HI + LOG_C_H[i], rh)
    s, e3 = _fast_two_sum(s, -0.5 * ph)
    lo = (e2 + e3) + (kd * LN2_LO + LOG_C_L[i]) + (rl - 0.5 * pl - rh * rl + q)
    return _fast_two_sum(s, lo)


@jit_hot
def log(x):
    """Natural logarithm (-inf at +-0, NaN below 0)."""
    x = float(x)
    if x > 0.0 and x < math.inf:
        return _log_dd(x)[0]
    if x == 0.0:
        return -math.inf
    if x == math.inf or x != x:
        return x + x
    return math.nan


@jit_hot
def _int_kind(y):
    """0 if y (finite, nonzero) is not an integer, 1 if an odd one, 2 if an even one."""
    iy = _bits(y)
    e = ((iy >> 52) & 0x7FF) - 1023
    if e < 0:
        return 0
    if e > 52:
        return 2
    if iy & ((1 << (52 - e)) - 1):
        return 0
    return 1 if (iy >> (52 - e)) & 1 else 2


@jit_hot
def _pow_special(x, y):
    """pow when x or y is 0, inf or NaN (not y = 0 or x = 1, handled before)."""
    if x != x or y != y:
        return x + y
    ax = abs(x)
    if abs(y) == math.inf:
        if ax == 1.0:
            return 1.0
        return 0.0 if (ax < 1.0) == (y > 0.0) else math.inf
    r = 0.0 if (y > 0.0) == (ax == 0.0) else math.inf  # x = +-0 or +-inf
    return -r if (_bits(x) < 0 and _int_kind(y) == 1) else r


@jit_hot
def pow(x, y):
    """x^y with C99's special cases (nearly correctly rounded, exact for exact results)."""
    x = float(x)
    y = float(y)
    if y == 0.0 or x == 1.0:
        return 1.0
    ax = abs(x)
    if not (ax > 0.0 and ax < math.inf and abs(y) < math.inf):
        return _pow_special(x, y)
    neg = False
    if x < 0.0:
        kind = _int_kind(y)
        if kind == 0:
            return math.nan
        neg = kind == 1
    lh, ll = _log_dd(ax)
    rough = y * lh
    if abs(rough) > 1100.0:  # certain overflow or underflow (and no overflow in the split)
        r = math.inf if rough > 0.0 else 0.0
    else:
        eh, el = _two_prod(y, lh)
        r = _exp_kernel(eh, el + y * ll)
    return -r if neg else r


# -- expm1, log1p, hyperbolic functions ---------------------------------------------------------
@jit_hot
def expm1(x):
    """e^x - 1, accurate for small x."""
    x = float(x)
    if not x < 710.0:
        return x + math.inf  # NaN stays NaN
    if x < -38.0:
        return -1.0  # e^x below half an ulp of 1
    if abs(x) < TWO_M54:
        return x  # +-0 and the subnormals too
    if abs(x) < TWO_M9:  # x + x^2/2 + ...: the double-double exp lacks the bits
        return x + x * x * (0.5 + x * (C3 + x * (C4 + x * (C5 + x * C6))))
    k, eh, el = _exp_dd(x)
    if k > 56:  # the 1 is below the rounding
        return _scale(eh + el, k)
    s = _pow2(k)
    h, lo = _two_sum(eh * s, -1.0)
    return h + (lo + el * s)


@jit_hot
def log1p(x):
    """log(1 + x), accurate for small x."""
    x = float(x)
    if not (x > -1.0 and x < math.inf):
        if x == -1.0:
            return -math.inf
        return math.nan if x < -1.0 else x + x
    if abs(x) < TWO_M54:
        return x  # +-0 and the subnormals too
    if abs(x) < TWO_M9:  # x - x^2/2 + ...: 1 + x would lose x's last bits
        return x + x * x * (-0.5 + x * (1.0 / 3.0 + x * (-0.25 + x * (0.2 + x * (
            -1.0 / 6.0 + x * (1.0 / 7.0 - x * 0.125))))))
    u, ul = _two_sum(1.0, x)
    h, lo = _log_dd(u)
    return h + (lo + ul / u)  # log(u + ul) = log(u) + ul/u to 2^-106


@jit_hot
def _exp_half_big(a):
    """e^a / 2 for a >= 21 (inf past 710.4758600739439)."""
    if a > 711.0:
        return math.inf
    k, eh, el = _exp_dd(a)
    return _scale(eh + el, k - 1)


@jit_hot
def _exp_pair(a):
    """e^a and e^-a for 0 <= a < 22 as double-doubles (eh, el, ih, il)."""
    k, eh, el = _exp_dd(a)
    s = _pow2(k)
    eh *= s
    el *= s
    ih = 1.0 / eh
    p, e = _two_prod(ih, eh)
    return eh, el, ih, (((1.0 - p) - e) - ih * el) / eh


@jit_hot
def sinh(x):
    """Hyperbolic sine."""
    x = float(x)
    a = abs(x)
    if not a < 21.0:
        return x + x if a != a else math.copysign(_exp_half_big(a), x)
    if a < TWO_M26:
        return x
    eh, el, ih, il = _exp_pair(a)
    sh, sl = _two_sum(eh, -ih)
    return math.copysign(0.5 * (sh + (sl + (el - il))), x)


@jit_hot
def cosh(x):
    """Hyperbolic cosine."""
    x = float(x)
    a = abs(x)
    if not a < 21.0:
        return x + x if a != a else _exp_half_big(a)
    if a < TWO_M27:
        return 1.0
    eh, el, ih, il = _exp_pair(a)
    sh, sl = _two_sum(eh, ih)
    return 0.5 * (sh + (sl + (el + il)))


@jit_hot
def tanh(x):
    """Hyperbolic tangent: (E - 1)/(E + 1), E = e^(2|x|) as a double-double."""
    x = float(x)
    a = abs(x)
    if not a < 22.0:  # tanh is 1 to within 2^-62 past 19.1
        return x + x if a != a else math.copysign(1.0, x)
    if a < TWO_M28:
        return x
    k, eh, el = _exp_dd(2.0 * a)
    s = _pow2(k)
    eh *= s
    el *= s
    # E >= 1 + 2^-27: fast two-sums are exact here
    nh, nl = _fast_two_sum(eh, -1.0)
    nh, nl = _fast_two_sum(nh, nl + el)
    dh, dl = _fast_two_sum(eh, 1.0)
    return math.copysign(_div_dd(nh, nl, dh, dl + el)[0], x)


# -- sin, cos, tan ------------------------------------------------------------------------------
@jit_hot
def _column(a0, a1, a2, a3, c):
    """sum_j a_j G[c + j] over the pieces of 2/pi that exist (c + j >= 0): exact (< 2^50)."""
    s = 0.0
    if c >= 0:
        s += a0 * TWO_OVER_PI[c]
    if c >= -1:
        s += a1 * TWO_OVER_PI[c + 1]
    if c >= -2:
        s += a2 * TWO_OVER_PI[c + 2]
    return s + a3 * TWO_OVER_PI[c + 3]


@jit_hot
def _rem_pio2_large(x):
    """Payne-Hanek: (n, yh, yl) with x - n pi/2 = yh + yl (absolute error ~2^-120: relative
    2^-59 for the double closest to a multiple of pi/2, 6381956970095103 2^797) for a
    finite |x| >= 2^20 pi/2 (any x with an exponent >= -32 in fact).

    x = M' 2^(24 q), M' = M 2^s (s = e mod 24) in four 24-bit pieces a_j; with
    2/pi = sum G[i] 2^(-24 (i + 1)), x 2/pi = sum_t S_t 2^(-24 t), S_t = sum_j a_j G[t + j +
    q - 1] (< 2^50, exact in doubles), the terms with t < 0 being multiples of 2^24, so of
    4. The first three terms are summed exactly modulo 4, the rest as a double-double."""
    ix = _bits(x)
    e = ((ix >> 52) & 0x7FF) - 1075
    mant = (ix & MANT_MASK) | (1 << 52)
    q = e // 24
    s = e - 24 * q
    lo = (mant & 0xFFFFFF) << s
    mid = ((mant >> 24) << s) + (lo >> 24)
    a0, a1 = float(lo & 0xFFFFFF), float(mid & 0xFFFFFF)
    a2, a3 = float((mid >> 24) & 0xFFFFFF), float(mid >> 48)
    c = q - 1
    acc = _column(a0, a1, a2, a3, c)
    acc -= 4.0 * math.floor(acc * 0.25)
    acc += _column(a0, a1, a2, a3, c + 1) * TWO_M24  # exact: 51 bits at most
    acc -= 4.0 * math.floor(acc * 0.25)
    acc += _column(a0, a1, a2, a3, c + 2) * (TWO_M24 * TWO_M24)
    acc -= 4.0 * math.floor(acc * 0.25)
    n = math.floor(acc + 0.5)
    acc -= n  # the fraction's first 48 bits, in [-0.5, 0.5)
    w = TWO_M24 * TWO_M24 * TWO_M24
    th, tl = _two_sum(_column(a0, a1, a2, a3, c + 3) * w,
                      _column(a0, a1, a2, a3, c + 4) * (w * TWO_M24))
    tl += (_column(a0, a1, a2, a3, c + 5) * (w * TWO_M24 * TWO_M24)
           + _column(a0, a1, a2, a3, c + 6) * (w * w))
    fh, fl = _two_sum(acc, th)
    fh, fl = _two_sum(fh, fl + tl)
    ph, pe = _two_prod(fh, PIO2_H)
    yh, yl = _fast_two_sum(ph, pe + (fh * PIO2_L + fl * PIO2_H))
    ni = int(n)
    if x < 0.0:
        return -ni, -yh, -yl
    return ni, yh, yl


@jit_hot
def _rem_pio2(x):
    """(n, yh, yl): x - n pi/2 = yh + yl, |yh| <= pi/4 (to a rounding); NaN for inf/NaN."""
    a = abs(x)
    if a <= PIO4_H:
        return 0, x, 0.0
    if a < MEDIUM:  # Cody-Waite: n PIO2_k exact, so the first difference too (Sterbenz)
        kd = x * INVPIO2 + SHIFT
        n = _bits(kd) - SHIFT_BITS
        kd -= SHIFT
        h, e1 = _two_sum(x - kd * PIO2_1, -(kd * PIO2_2))
        h, e2 = _two_sum(h, -(kd * PIO2_3))
        yh, yl = _fast_two_sum(h, (e1 + e2) - kd * PIO2_4)
        return n, yh, yl
    if not a < math.inf:
        return 0, x - x, 0.0
    return _rem_pio2_large(x)


@jit_hot
def _sin_dd(xh, xl):
    """sin(xh + xl), |xh| <= pi/4 (+2^-20), as a double-double (relative error < 2^-62)."""
    zh, zl = _two_sqr(xh)
    ch, cl = _two_prod(zh, xh)
    cl += zl * xh  # x^3 = ch + cl
    th, tl = _two_prod(ch, S1_H)
    tl += ch * S1_L + cl * S1_H  # -x^3/6 = th + tl
    z = zh
    rest = ch * z * (SQ0 + z * (SQ1 + z * (SQ2 + z * (SQ3 + z * (SQ4 + z * SQ5)))))
    h, lo = _fast_two_sum(xh, th)
    # sin(xh + xl) = sin(xh) + xl cos(xh) to 2^-106, cos(xh) to its x^6 term
    return _fast_two_sum(h, lo + (tl + rest + xl * (1.0 - z * (0.5 - z * C4))))


@jit_hot
def _cos_dd(xh, xl):
    """cos(xh + xl), |xh| <= pi/4 (+2^-20), as a double-double (error < 2^-64)."""
    zh, zl = _two_sqr(xh)
    hz = 0.5 * zh
    w = 1.0 - hz
    e = (1.0 - w) - hz  # exact: 1 - hz = w + e
    qh, ql = _two_sqr(zh)
    ql += 2.0 * zh * zl  # x^4 = qh + ql
    th, tl = _two_prod(qh, C24_H)
    tl += qh * C24_L + ql * C24_H  # x^4/24 = th + tl
    z = zh
    rest = qh * z * (CR0 + z * (CR1 + z * (CR2 + z * (CR3 + z * (CR4 + z * CR5)))))
    s, e2 = _two_sum(w, th)
    # cos(xh + xl) = cos(xh) - xl sin(xh) to 2^-106, sin(xh) to its x^5 term
    return _fast_two_sum(s, (e + e2) + (tl - 0.5 * zl + rest - xl * xh * (1.0 - z * C3)))


@jit_hot
def sin(x):
    """Sine (NaN for +-inf)."""
    x = float(x)
    if abs(x) < TWO_M26:
        return x
    n, yh, yl = _rem_pio2(x)
    h = _cos_dd(yh, yl)[0] if n & 1 else _sin_dd(yh, yl)[0]
    return -h if n & 2 else h


@jit_hot
def cos(x):
    """Cosine (NaN for +-inf)."""
    x = float(x)
    if abs(x) < TWO_M27:
        return 1.0
    n, yh, yl = _rem_pio2(x)
    h = _sin_dd(yh, yl)[0] if n & 1 else _cos_dd(yh, yl)[0]
    return -h if (n + 1) & 2 else h


@jit_hot
def tan(x):
    """Tangent (NaN for +-inf): sin/cos of the reduced argument divided as double-doubles."""
    x = float(x)
    if abs(x) < TWO_M27:
        return x
    n, yh, yl = _rem_pio2(x)
    sh, sl = _sin_dd(yh, yl)
    ch, cl = _cos_dd(yh, yl)
    if n & 1:
        return -_div_dd(ch, cl, sh, sl)[0]
    return _div_dd(sh, sl, ch, cl)[0]


# -- atan, atan2, asin, acos ----------------------------------------------------------------------
@jit_hot
def _atan_dd(th, tl):
    """atan(th + tl) for th in [0, 1 + 2^-50] as a normalized double-double (< 2^-64)."""
    j = int(th * 16.0 + 0.5)
    c = j * 0.0625
    nh, nl = _two_sum(th - c, tl)  # th - c exact (Sterbenz)
    dh, dl = _two_prod(th, c)
    dh, de = _fast_two_sum(1.0, dh)
    uh, ul = _div_dd(nh, nl, dh, de + (dl + tl * c))  # u = (t - c)/(1 + t c), |u| <= 1/32
    u2 = uh * uh
    poly = uh * u2 * (-1.0 / 3.0 + u2 * (0.2 + u2 * (-1.0 / 7.0 + u2 * (
        1.0 / 9.0 + u2 * (-1.0 / 11.0 + u2 * (1.0 / 13.0))))))
    h, lo = _two_sum(ATAN_H[j], uh)
    return _fast_two_sum(h, lo + (ATAN_L[j] + ul + poly))


@jit_hot
def _atan_ratio(nh, nl, dh, dl):
    """atan(n/d) for double-doubles n, d >= 0 (not both 0), scaled so that neither the
    quotient nor Dekker's products overflow: a normalized double-double."""
    if nh <= dh:
        th, tl = _div_dd(nh, nl, dh, dl)
        return _atan_dd(th, tl)
    th, tl = _div_dd(dh, dl, nh, nl)
    ah, al = _atan_dd(th, tl)
    h, lo = _fast_two_sum(PIO2_H, -ah)
    return _fast_two_sum(h, lo + (PIO2_L - al))


@jit_hot
def atan(x):
    """Arctangent, in [-pi/2, pi/2]."""
    x = float(x)
    a = abs(x)
    if not a < TWO_P60:  # pi/2 - 1/a rounds to PIO2_H
        return x + x if a != a else math.copysign(PIO2_H, x)
    if a < TWO_M27:
        return x
    return math.copysign(_atan_ratio(a, 0.0, 1.0, 0.0)[0], x)


@jit_hot
def _atan2_finite(ay, ax, neg):
    """atan2 of finite nonzero |y| = ay and |x| = ax, x < 0 when ``neg``: a double."""
    d = _ilogb(ay) - _ilogb(ax)
    if d > 60:  # pi/2 -+ ax/ay rounds to PIO2_H
        return PIO2_H
    if d < -60:  # ay/ax (correctly rounded; the cubic term is below 2^-120), or pi - it
        return PI_H if neg else ay / ax
    k = -_ilogb(ax)  # bring ax to [1, 2): exact, ay stays within 2^61
    h, lo = _atan_ratio(_scale(ay, k), 0.0, _scale(ax, k), 0.0)
    if neg:
        s, e = _fast_two_sum(PI_H, -h)
        return s + (e + (PI_L - lo))
    return h


@jit_hot
def atan2(y, x):
    """The angle of (x, y) in [-pi, pi], with C99's signed zeros and infinities."""
    y = float(y)
    x = float(x)
    if x != x or y != y:
        return x + y
    ay = abs(y)
    ax = abs(x)
    if ay == 0.0 or (ax == math.inf and ay < math.inf):  # on the x axis: 0 or pi
        return math.copysign(PI_H if _bits(x) < 0 else 0.0, y)
    if ax == 0.0 or ay == math.inf:
        if ax == math.inf:
            return math.copysign(PI3O4_H if x < 0.0 else PIO4_H, y)
        return math.copysign(PIO2_H, y)
    return math.copysign(_atan2_finite(ay, ax, x < 0.0), y)


@jit_hot
def _sqrt_one_minus_sq(a):
    """sqrt(1 - a^2) for 0 <= a < 1 as a double-double (1 - a^2 exact to 2^-104)."""
    ph, pl = _two_sqr(a)
    dh, dl = _fast_two_sum(1.0, -ph)
    dh, dl = _fast_two_sum(dh, dl - pl)
    sh = math.sqrt(dh)
    p, e = _two_sqr(sh)
    return sh, (((dh - p) - e) + dl) / (2.0 * sh)


@jit_hot
def asin(x):
    """Arcsine, in [-pi/2, pi/2] (NaN outside [-1, 1])."""
    x = float(x)
    a = abs(x)
    if not a < 1.0:
        if a == 1.0:
            return math.copysign(PIO2_H, x)
        return x + x if x != x else math.nan
    if a < TWO_M26:
        return x
    sh, sl = _sqrt_one_minus_sq(a)
    return math.copysign(_atan_ratio(a, 0.0, sh, sl)[0], x)


@jit_hot
def acos(x):
    """Arccosine, in [0, pi] (NaN outside [-1, 1])."""
    x = float(x)
    a = abs(x)
    if not a < 1.0:
        if x == 1.0:
            return 0.0
        if x == -1.0:
            return PI_H
        return x + x if x != x else math.nan
    if a < TWO_M57:
        return PIO2_H
    sh, sl = _sqrt_one_minus_sq(a)
    h, lo = _atan_ratio(sh, sl, a, 0.0)
    if x < 0.0:
        s, e = _fast_two_sum(PI_H, -h)
        return s + (e + (PI_L - lo))
    return h
