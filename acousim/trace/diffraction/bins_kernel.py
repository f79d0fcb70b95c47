"""Compiled read-back of the edge-to-edge integral's bins
(:func:`acousim.trace.diffraction.pairs_compiled.compiled_elements`; numba,
optional: without numba the numpy form there runs).

One pass over the bins in the order of ``np.nonzero(count)`` (pair by pair, bin by
bin): each filled bin's mean path and points (sums over its weight) and its last
leg, the same operations in the same order as the numpy form (divisions and a
norm summed x, y, z), so the elements are the same bit for bit
(``tests/acousim/trace/diffraction/test_bins_kernel.py``).
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def read_bins(count, acc, receiver, idx, out):  # pragma: no cover - compiled
    """The elements of the filled bins (count (N, B) > 0; acc (N, B, 9): amplitude,
    weight, weighted path, weighted points on edge 1 and edge 2) into out (first
    point, point (K, 3), first leg, second leg, amplitude, pair (K,)), K at most
    N B; returns K.  receiver (3,); idx (N,): each row's pair."""
    q1, q2, first, second, amp, pair = out
    n = 0
    for k in range(count.shape[0]):
        for b in range(count.shape[1]):
            if count[k, b] == 0:
                continue
            a = acc[k, b]
            w = a[1] if a[1] > 0 else 1.0
            length = a[2] / w
            for c in range(3):
                q1[n, c] = a[3 + c] / w
                q2[n, c] = a[6 + c] / w
            dx, dy, dz = q2[n, 0] - receiver[0], q2[n, 1] - receiver[1], q2[n, 2] - receiver[2]
            leg = math.sqrt(dx * dx + dy * dy + dz * dz)
            first[n], second[n], amp[n], pair[n] = length - leg, leg, a[0], idx[k]
            n += 1
    return n
