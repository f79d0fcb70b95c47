"""Standard normal draws of a numpy ``Generator``: ``rng.standard_normal(shape)``,
the same float64 values bit for bit and the generator left in the same state,
about three times cheaper when the bit generator is numpy's PCG64 and the compiled
kernel (:mod:`acousim.synth._normal_kernel`, numba) is there; numpy's own call
otherwise.

The kernel runs numpy's ziggurat (256 layers) on PCG64's outputs.  Its tables are
numpy's, read off numpy's own draws (:func:`ziggurat_tables`): PCG64's state can be
set so that its next 64-bit output is any chosen word, and a draw whose magnitude
bits are 1 is accepted at once as exactly the layer's scale factor w_i; a layer's
threshold k_i is ``round(2**52 w_(i-1) / w_i)`` in float64 (the base layer's
``round(2**52 r / x_0)``, x_i = 2**52 w_i, r = x_255; the top layer's 0), each checked
on numpy's draws on either side of it.  The densities ``f_i = exp(-x_i**2 / 2)``
(f_0 = 1) are libm's ``exp(-0.5 * x_i * x_i)``, as the wedge test computes its
``exp(-0.5 * x * x)`` (correctly rounded for all 255): their last bits cannot be read
off the draws (a wedge test that a one-ulp change decides has odds of about 1e-16),
they are checked by the agreement of many draws instead (``benchmarks/normal_draws``).
When any check fails (another numpy), numpy draws.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

from processing.base.kernels import optional_kernel

__all__ = ["standard_normal", "ziggurat_tables"]

_MULT = 0x2360ED051FC65DA44385DF649FCCF645  # PCG64's multiplier
_WORD = 2**64 - 1
_STATE = 2**128 - 1


def standard_normal(rng: np.random.Generator, shape) -> np.ndarray:
    """``rng.standard_normal(shape)`` (float64, `shape` an int or a tuple): the same
    values, `rng` advanced as numpy advances it."""
    bits = rng.bit_generator
    kernel = optional_kernel("acousim.synth._normal_kernel", "standard_normal")
    tables = ziggurat_tables() if kernel is not None else None
    if tables is None or type(bits) is not np.random.PCG64:
        return rng.standard_normal(shape)
    out = np.empty(shape)
    with bits.lock:  # as numpy's own draws hold it
        state = bits.state
        s = _halves(state["state"]["state"], state["state"]["inc"])
        kernel(s, out.reshape(-1), *tables)
        state["state"]["state"] = (int(s[0]) << 64) | int(s[1])
        bits.state = state
    return out


def _halves(state: int, inc: int) -> np.ndarray:
    """PCG64's state and increment as the kernel's uint64 [hi, lo, inc hi, inc lo]."""
    return np.array([state >> 64, state & _WORD, inc >> 64, inc & _WORD], dtype=np.uint64)


class _Probe:
    """numpy's draws from chosen PCG64 outputs: :meth:`draw` sets a private PCG64 so
    that its next output is `word`, draws one standard normal, and counts the outputs
    the draw took."""

    def __init__(self) -> None:
        self.bits = np.random.PCG64(0)
        self.rng = np.random.Generator(self.bits)
        self.inc = self.bits.state["state"]["inc"]
        self.back = pow(_MULT, -1, 2**128)  # undoes a step's multiply

    def draw(self, layer: int, rabs: int) -> tuple[float, int]:
        """(numpy's draw, outputs taken) when the next output has the ziggurat layer
        `layer` (8 bits), sign bit 0 and magnitude `rabs` (52 bits)."""
        word = layer | (rabs << 9)
        hi = 0x5DEECE66D1234567  # any: the top 6 bits give the rotation
        rot = hi >> 58
        lo = (((word << rot) | (word >> (64 - rot))) & _WORD) ^ hi
        start = ((((hi << 64) | lo) - self.inc) * self.back) & _STATE
        state = self.bits.state
        state["state"]["state"] = start
        self.bits.state = state
        value = float(self.rng.standard_normal())
        end, taken = self.bits.state["state"]["state"], 0
        while start != end and taken < 1000:
            start, taken = (start * _MULT + self.inc) & _STATE, taken + 1
        return value, taken


@cache
def ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """numpy's ziggurat tables (see the module docstring): the scale factors w (256,)
    float64, the integer thresholds k (256,) uint64 and the densities f (256,)
    float64 (unit peak), read off numpy's draws; None when they do not check out."""
    probe = _Probe()
    drawn = [probe.draw(i, 1) for i in range(256)]  # accepted: the value is w_i
    if [taken for _, taken in drawn] != [1, 2] + [1] * 254:  # layer 1: all by its wedge
        return None
    w = np.array([value for value, _ in drawn])
    x = w * 2.0**52  # x_0 is the base layer's width v / f(r), x_255 = r
    ratios = np.concatenate([x[255:] / x[:1], [0.0], x[1:-1] / x[2:]])
    k = [round(ratio * 2.0**52) for ratio in ratios]
    if not all(_threshold_holds(probe, i, k[i], w[i]) for i in range(256)):
        return None
    f = [1.0] + [math.exp(-0.5 * edge * edge) for edge in x[1:]]  # libm's, as the wedges'
    return w, np.array(k, dtype=np.uint64), np.array(f)


def _threshold_holds(probe: _Probe, layer: int, k: int, w: float) -> bool:
    """Whether numpy takes magnitude k - 1 at once (one output, the value (k - 1) w)
    and k not (more outputs) in this ziggurat layer."""
    below = probe.draw(layer, k - 1) if k else (0.0, 1)
    return below == ((k - 1) * w if k else 0.0, 1) and probe.draw(layer, k)[1] > 1
