"""Compiled sum of products of the FFT route (:func:`acousim.synth.render._sets_by_fft`;
numba, optional: without numba the same sum runs in numpy).

The spectra of a block's sets of impulses times their sets' filters, summed over
the sets, in one pass over the band per microphone (numpy makes a product array per
set and adds it: the band's memory touched twice per set).  The GIL is released.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True)
def summed_products(spectra, filt, b0, out):  # pragma: no cover - compiled
    """out[c, b0 + i] <- sum_q spectra[q, c, b0 + i] filt[q, i] for the bins of
    `filt` (R, F) from bin b0, c < out.shape[0]; spectra (R, C, bins), summed in the
    order of q, in their precision (complex64 or complex128)."""
    R, F = filt.shape
    for c in range(out.shape[0]):
        o = out[c, b0 : b0 + F]
        s0, f0 = spectra[0, c, b0 : b0 + F], filt[0]
        for i in range(F):
            o[i] = s0[i] * f0[i]
        for q in range(1, R):
            sq, fq = spectra[q, c, b0 : b0 + F], filt[q]
            for i in range(F):
                o[i] += sq[i] * fq[i]
