"""Compiled passes of the signal model (:mod:`acousim.synth.signal_model`; numba,
optional: without numba the same results in numpy).

:func:`mean_squares`: the paths' mean squared gains over the microphones, summed
in numpy's order for a contiguous reduction (its pairwise summation: eight
interleaved partial sums), so the results are numpy's bits without the transposed
copy of the gains numpy makes to select the echoes' columns.  The GIL is released.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def mean_squares(gain, out):  # pragma: no cover - compiled
    """out (N,) <- ``mean_m gain[m, n]^2`` summed as numpy sums a contiguous run of
    M <= 128 terms a_m (its block, PW_BLOCKSIZE; the caller checks M): fewer than 8
    in order; else 8 partial sums ``r_j = a_j + a_(8+j) + ...`` over the multiples of
    8, then ``((r_0 + r_1) + (r_2 + r_3)) + ((r_4 + r_5) + (r_6 + r_7))``, then the
    rest in order; divided by M.  gain (M, N) float64, any layout."""
    M, N = gain.shape
    full = M - M % 8
    r = np.empty(8)
    for c in range(N):
        if M < 8:
            s = 0.0
            for i in range(M):
                s += gain[i, c] * gain[i, c]
        else:
            for j in range(8):
                r[j] = gain[j, c] * gain[j, c]
            for i in range(8, full, 8):
                for j in range(8):
                    r[j] += gain[i + j, c] * gain[i + j, c]
            s = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
            for i in range(full, M):
                s += gain[i, c] * gain[i, c]
        out[c] = s / M
