"""Branch-free log, log1p, expm1 and atan for the compiled edge-to-edge integral
(numba; :mod:`acousim.trace.diffraction.pair_kernel`).

The library's functions are calls that stop a loop from running on vector
registers; these are inlined polynomials of a few multiply-adds (the exponent
split off by reading the float's bits), so the loops over a side's elements that
call them vectorize.  Each is within a few ulp of the exact value over the range
the integral uses (``tests/acousim/trace/diffraction/test_math_kernel.py``
measures them against numpy): relative error below 1e-15, far below the
integral's own (its elements' width).

- :func:`log_pos`: log(x) for positive finite x (by x = 2^k m, m in
  [sqrt(1/2), sqrt(2)), log m = 2 atanh((m - 1) / (m + 1)) as its series);
- :func:`log1p_pos`: log(1 + s) for s >= 0, with the rounding of 1 + s corrected;
- :func:`expm1_pos`, :func:`exp_pos`: exp(x) - 1 and exp(x) for 0 <= x <= 700
  (x = k ln 2 + r, |r| <= ln2 / 2, expm1(r) as its series);
- :func:`cos_quarter`: cos(pi t / 2) for t in [0, 1] (its series);
- :func:`atan_any`: atan(z) for any z (1/|z| past 1, then two halvings
  tan(a / 2) = t / (1 + sqrt(1 + t^2)), then the series).
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["atan_any", "cos_quarter", "exp_pos", "expm1_pos", "log1p_pos", "log_pos"]

#: ln 2 split in two: the first has its last 11 bits zero (k ln2_hi exact)
LN2_HI = 6.93147180369123816490e-01
LN2_LO = 1.90821492927058770002e-10
LN2 = math.log(2.0)
#: the bits of sqrt(1/2): mantissas are taken relative to it
SQRT_HALF_BITS = 0x3FE6A09E667F3BCD
MANTISSA = 52
#: 1 / i (INV[0] unused), the series' coefficients (constants of the compiled code)
INV = tuple(1.0 / i if i else 0.0 for i in range(24))
_jit = njit(cache=True, nogil=True, error_model="numpy", inline="always")


@intrinsic
def _bits(typingctx, x):  # pragma: no cover - compiled
    """The int64 with the bits of the float64 x."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _float(typingctx, b):  # pragma: no cover - compiled
    """The float64 with the bits of the int64 b."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


@_jit
def _log_mantissa(x):  # pragma: no cover - compiled
    """(k, f, t): x = 2^k (1 + f) with 1 + f in [sqrt(1/2), sqrt(2)), t = f / (2 + f)."""
    b = _bits(x)
    k = (b - SQRT_HALF_BITS) >> MANTISSA
    f = _float(b - (k << MANTISSA)) - 1.0  # exact (Sterbenz)
    return k, f, f / (2.0 + f)


@_jit
def _atanh_series(t):  # pragma: no cover - compiled
    """2 atanh(t) for |t| <= 0.1716 (3 - 2 sqrt 2): 2 (t + t^3/3 + ... + t^19/19);
    the next term is below 2e-17 of the sum."""
    t2 = t * t
    p = 2.0 / 19
    p = p * t2 + 2.0 / 17
    p = p * t2 + 2.0 / 15
    p = p * t2 + 2.0 / 13
    p = p * t2 + 2.0 / 11
    p = p * t2 + 2.0 / 9
    p = p * t2 + 2.0 / 7
    p = p * t2 + 2.0 / 5
    p = p * t2 + 2.0 / 3
    return t * 2.0 + t * (t2 * p)


@_jit
def log_pos(x):  # pragma: no cover - compiled
    """log(x) for positive, finite, normal x."""
    k, _, t = _log_mantissa(x)
    return k * LN2_HI + (k * LN2_LO + _atanh_series(t))


@_jit
def log1p_pos(s):  # pragma: no cover - compiled
    """log(1 + s) for finite s >= 0: log of x = 1 + s (rounded) plus (s - (x - 1)) / x,
    the rounding's share (x - 1 is exact)."""
    x = 1.0 + s
    k, _, t = _log_mantissa(x)
    return k * LN2_HI + (k * LN2_LO + (_atanh_series(t) + (s - (x - 1.0)) / x))


@_jit
def _exp_split(x):  # pragma: no cover - compiled
    """(2^k, expm1(r)) of x = k ln 2 + r, k the nearest integer to x / ln 2 (|r| <=
    0.35; expm1(r) as its series to r^14 / 14!, whose next term is below 1e-19);
    for finite x with -1022 <= k <= 1023."""
    k = int(math.floor(x * (1.0 / LN2) + 0.5))
    r = (x - k * LN2_HI) - k * LN2_LO
    p = 1.0 + r * INV[14]
    p = 1.0 + r * INV[13] * p
    p = 1.0 + r * INV[12] * p
    p = 1.0 + r * INV[11] * p
    p = 1.0 + r * INV[10] * p
    p = 1.0 + r * INV[9] * p
    p = 1.0 + r * INV[8] * p
    p = 1.0 + r * INV[7] * p
    p = 1.0 + r * INV[6] * p
    p = 1.0 + r * INV[5] * p
    p = 1.0 + r * INV[4] * p
    p = 1.0 + r * INV[3] * p
    p = 1.0 + r * INV[2] * p
    return _float((k + 1023) << MANTISSA), r * p


@_jit
def expm1_pos(x):  # pragma: no cover - compiled
    """exp(x) - 1 for 0 <= x <= 700: 2^k expm1(r) + (2^k - 1) (:func:`_exp_split`)."""
    two_k, em = _exp_split(x)
    return two_k * em + (two_k - 1.0)


@_jit
def exp_pos(x):  # pragma: no cover - compiled
    """exp(x) for 0 <= x <= 700: 2^k (1 + expm1(r)) (:func:`_exp_split`)."""
    two_k, em = _exp_split(x)
    return two_k + two_k * em


@_jit
def atan_any(z):  # pragma: no cover - compiled
    """atan(z) for any z (NaN for NaN): of w = min(|z|, 1 / |z|) <= 1, halved twice
    (|w| <= tan(pi / 16)) and its series to w^23 / 23 (the next term below 1e-17 of
    it), times 4; pi / 2 minus it for |z| > 1; z's sign."""
    a = abs(z)
    w = 1.0 / a if a > 1.0 else a
    w = w / (1.0 + math.sqrt(1.0 + w * w))
    w = w / (1.0 + math.sqrt(1.0 + w * w))
    w2 = w * w
    p = -INV[23]  # w (1 + w^2 p): p = -1/3 + w^2/5 - ... - w^20/23, by Horner
    p = p * w2 + INV[21]
    p = p * w2 - INV[19]
    p = p * w2 + INV[17]
    p = p * w2 - INV[15]
    p = p * w2 + INV[13]
    p = p * w2 - INV[11]
    p = p * w2 + INV[9]
    p = p * w2 - INV[7]
    p = p * w2 + INV[5]
    p = p * w2 - INV[3]
    out = 4.0 * (w + w * (w2 * p))
    out = (0.5 * math.pi - out) if a > 1.0 else out
    return math.copysign(out, z)


@_jit
def cos_quarter(t):  # pragma: no cover - compiled
    """cos(pi t / 2) for 0 <= t <= 1: the series in x = pi t / 2 <= pi / 2 to x^20 / 20!
    (the next term below 2e-17)."""
    x = 0.5 * math.pi * t
    x2 = x * x
    p = 1.0 - x2 * (INV[20] * INV[19])
    p = 1.0 - x2 * (INV[18] * INV[17]) * p
    p = 1.0 - x2 * (INV[16] * INV[15]) * p
    p = 1.0 - x2 * (INV[14] * INV[13]) * p
    p = 1.0 - x2 * (INV[12] * INV[11]) * p
    p = 1.0 - x2 * (INV[10] * INV[9]) * p
    p = 1.0 - x2 * (INV[8] * INV[7]) * p
    p = 1.0 - x2 * (INV[6] * INV[5]) * p
    p = 1.0 - x2 * (INV[4] * INV[3]) * p
    return 1.0 - x2 * 0.5 * p
