"""Compiled standard normal draws of numpy's ``Generator(PCG64)`` (numba, optional:
without numba :mod:`acousim.synth.normal` calls numpy), the same float64 values.

PCG64 (a 128-bit linear congruential generator, XSL-RR output: the xor of the
state's halves rotated right by the state's top 6 bits) runs here on the state's
two 64-bit halves; the draws are the ziggurat of numpy's ``standard_normal`` (256
layers, Marsaglia & Tsang): each attempt takes one 64-bit output, its low 8 bits
the layer, the next bit the sign, the next 52 bits the magnitude ``rabs``; accepted
at once when ``rabs`` is below the layer's threshold, otherwise tested in the
layer's wedge (one more uniform double) or, in the base layer, drawn from the tail
beyond r (pairs of uniform doubles).  The tables come from
:func:`acousim.synth.normal.ziggurat_tables`.  The GIL is released.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

#: PCG64's multiplier (the default 128-bit multiplier of the PCG family), in halves
MULT_HI = np.uint64(0x2360ED051FC65DA4)
MULT_LO = np.uint64(0x4385DF649FCCF645)


@intrinsic
def _mulhi(typingctx, a, b):  # pragma: no cover - compiled
    """The high 64 bits of the 128-bit product of two uint64 (one machine multiply)."""
    sig = types.uint64(types.uint64, types.uint64)

    def codegen(context, builder, signature, args):
        # numba's own dependency, imported here: without numba, numba is the import
        # that fails (the optional kernel's test of a missing extra)
        from llvmlite import ir

        wide = ir.IntType(128)
        product = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(product, ir.Constant(wide, 64)), ir.IntType(64))

    return sig, codegen


@njit(cache=True, nogil=True, inline="always")
def _next(hi, lo, inc_hi, inc_lo):  # pragma: no cover - compiled
    """One PCG64 step and output: the state (hi, lo) becomes ``state * MULT + inc``
    (mod 2**128); (new hi, new lo, the output of the new state), all uint64."""
    new_lo = lo * MULT_LO
    new_hi = _mulhi(lo, MULT_LO) + lo * MULT_HI + hi * MULT_LO
    lo = new_lo + inc_lo
    hi = new_hi + inc_hi + np.uint64(lo < new_lo)
    x = hi ^ lo
    rot = hi >> np.uint64(58)
    return hi, lo, (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))


@njit(cache=True, nogil=True, inline="always")
def _uniform(hi, lo, inc_hi, inc_lo):  # pragma: no cover - compiled
    """One step and a uniform double in [0, 1): the output's top 53 bits times 2**-53."""
    hi, lo, raw = _next(hi, lo, inc_hi, inc_lo)
    return hi, lo, np.float64(raw >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, nogil=True)
def _slow(s, idx, rabs, x, tables):  # pragma: no cover - compiled
    """The attempt whose ``rabs`` is not below its layer's threshold, s the state as in
    :func:`standard_normal` (advanced past the uniforms taken): NaN when rejected
    (the caller makes a new attempt), else the draw."""
    w, f = tables
    hi, lo, inc_hi, inc_lo = s[0], s[1], s[2], s[3]
    if idx == 0:  # the tail beyond r = w[255] * 2**52, by pairs of exponentials
        r = w[255] * 4503599627370496.0
        while True:
            hi, lo, u = _uniform(hi, lo, inc_hi, inc_lo)
            xx = -(1.0 / r) * math.log1p(-u)
            hi, lo, u = _uniform(hi, lo, inc_hi, inc_lo)
            yy = -math.log1p(-u)
            if yy + yy > xx * xx:
                s[0], s[1] = hi, lo
                return -(r + xx) if (rabs >> np.uint64(8)) & np.uint64(1) else r + xx
    hi, lo, u = _uniform(hi, lo, inc_hi, inc_lo)
    s[0], s[1] = hi, lo
    if (f[idx - 1] - f[idx]) * u + f[idx] < math.exp(-0.5 * x * x):
        return x
    return np.nan


@njit(cache=True, nogil=True)
def standard_normal(s, out, w, k, f):  # pragma: no cover - compiled
    """out (n,) float64 <- n standard normal draws from the PCG64 state s (uint64
    [state hi, state lo, increment hi, increment lo], advanced in place past the
    outputs taken); w, f (256,) float64 and k (256,) uint64 the ziggurat's scale
    factors, densities and integer thresholds."""
    mask = np.uint64(0x000FFFFFFFFFFFFF)
    hi, lo, inc_hi, inc_lo = s[0], s[1], s[2], s[3]
    for i in range(out.shape[0]):
        while True:
            hi, lo, r = _next(hi, lo, inc_hi, inc_lo)
            idx = np.intp(r & np.uint64(0xFF))
            rabs = (r >> np.uint64(9)) & mask
            x = np.float64(np.int64(rabs)) * w[idx]  # exact: rabs < 2**52
            if r & np.uint64(0x100):
                x = -x
            if rabs < k[idx]:
                break
            s[0], s[1] = hi, lo
            x = _slow(s, idx, rabs, x, (w, f))
            hi, lo = s[0], s[1]
            if not np.isnan(x):
                break
        out[i] = x
    s[0], s[1] = hi, lo
