"""Compiled per-microphone part of the path responses
(:func:`acousim.synth.render._response_factors`; numba, optional: without numba the
same formulas run in numpy, an array at a time).

The paths' mean lengths over the microphones, the gains times the absorption of
each microphone's difference from that mean, and the paths' RMS gains, in two
passes over the (M, N) arrays instead of numpy's eight.  The sums run in the order
of the microphones, as numpy's reductions along the first axis do; the exponential
of the small arguments (``|x| <= EXP_SERIES_MAX``, millimetres at a few dB/m) is its
Taylor series to x^7 (error below 1e-18 of the value there: within a unit of the
last place of numpy's), of larger ones the library's.  The GIL is released.
"""

from __future__ import annotations

import math

from numba import njit

#: the largest |x| whose exp(x) is summed as a series (x^8 / 8! < 1e-21 there)
EXP_SERIES_MAX = 0.01


@njit(cache=True, nogil=True)
def _exp_series(x):  # pragma: no cover - compiled
    """exp(x) to x^7, Horner's form (|x| <= EXP_SERIES_MAX)."""
    return 1.0 + x * (
        1.0 + x * (0.5 + x * (1 / 6 + x * (1 / 24 + x * (1 / 120 + x * (1 / 720 + x / 5040)))))
    )


@njit(cache=True, nogil=True)
def mic_gains(gain, length, c, out, mean, weight):  # pragma: no cover - compiled
    """mean (N,) <- the mean over m of length (M, N); out (M, N) <- ``gain exp(c
    (length - mean))``; weight (N,) <- ``sqrt(mean over m of out^2) + 1e-300``."""
    M, N = gain.shape
    mean[:] = 0.0
    for m in range(M):
        lm = length[m]
        for n in range(N):
            mean[n] += lm[n]
    reach = 0.0
    for n in range(N):
        mean[n] /= M
    for m in range(M):
        for n in range(N):
            reach = max(reach, abs(c * (length[m, n] - mean[n])))
    weight[:] = 0.0
    for m in range(M):
        lm, gm, om = length[m], gain[m], out[m]
        if reach <= EXP_SERIES_MAX:
            for n in range(N):
                om[n] = gm[n] * _exp_series(c * (lm[n] - mean[n]))
        else:
            for n in range(N):
                om[n] = gm[n] * math.exp(c * (lm[n] - mean[n]))
        for n in range(N):
            weight[n] += om[n] * om[n]
    for n in range(N):
        weight[n] = math.sqrt(weight[n] / M) + 1e-300
