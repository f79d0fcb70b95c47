"""The compiled read-back of the edge-to-edge bins
(:func:`acousim.trace.diffraction.bins_kernel.read_bins`) against the same steps
written out here on whole arrays (every filled bin in row-major order: its mean
path and points over its weight, its last leg), on random sums with empty and
weightless bins among them: the same numbers bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")


def test_read_bins_is_the_bins_means():
    from acousim.trace.diffraction.bins_kernel import read_bins

    rng = np.random.default_rng(4)
    n, n_bins = 13, 17
    count = rng.integers(0, 4, (n, n_bins)) * (rng.random((n, n_bins)) < 0.4)
    acc = rng.normal(size=(n, n_bins, 9))
    acc[:, :, 1] = np.abs(acc[:, :, 1]) * (rng.random((n, n_bins)) < 0.9)  # some weightless
    idx = np.sort(rng.choice(100, n, replace=False))
    receiver = np.array([0.3, -0.2, 1.1])
    size = count.size
    out = (np.empty((size, 3)), np.empty((size, 3)), *(np.empty(size) for _ in range(3)))
    out += (np.empty(size, idx.dtype),)
    got = read_bins(count, acc, receiver, idx, out)
    # by hand
    k, b = np.nonzero(count)
    a = acc[k, b]
    w = np.where(a[:, 1] > 0, a[:, 1], 1.0)
    q2 = a[:, 6:9] / w[:, None]
    leg = np.sqrt(((q2 - receiver) ** 2).sum(axis=1))
    want = (a[:, 3:6] / w[:, None], q2, a[:, 2] / w - leg, leg, a[:, 0], idx[k])
    assert got == k.size > 0
    for have, expect in zip(out, want):
        np.testing.assert_array_equal(have[:got], expect)
