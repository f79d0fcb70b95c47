"""Matched filter (eq. 3 of the paper): cross-correlation with the emitted call.

``y[..., n] = sum_k x[..., n + k] * s_e[k]`` — zero lag at output sample n means an
echo that *starts* at sample n, so the output keeps the time axis of the input: a
reflector at range r peaks at ``emission_index + round(2 r / c * fs)``.
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sfft

from processing.base.errors import InputError, refuse_non_finite

__all__ = ["matched_filter"]


def matched_filter(x: np.ndarray, template: np.ndarray, *, axis: int = -1) -> np.ndarray:
    """Cross-correlate each channel with `template`, FFT based.

    Parameters
    ----------
    x : ndarray, shape (..., T)
        Real signals (any leading dimensions, e.g. (M, T) or (K, M, T)).
    template : ndarray, shape (L,)
        The emitted call, sampled at the rate of `x`.

    Returns
    -------
    ndarray, shape like `x`, float64
        Output at non-negative lags, aligned with the input's time axis.

    A template that is not a non-empty 1-D array, or a non-finite sample of either
    (one NaN would spread over its whole channel), is an
    :class:`processing.InputError` naming the argument (and the channel and sample).
    """
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, -1)
    h = np.asarray(template, dtype=np.float64)
    if h.ndim != 1 or h.size == 0:
        raise InputError("must be a non-empty 1-D array", key="template", value=h.shape)
    refuse_non_finite(x, "x")
    refuse_non_finite(h, "template")
    T = x.shape[-1]
    n = sfft.next_fast_len(T + h.size - 1, real=True)
    X = sfft.rfft(x, n, axis=-1)
    H = sfft.rfft(h, n)
    y = sfft.irfft(X * np.conj(H), n, axis=-1)[..., :T]
    return np.moveaxis(y, -1, axis)
