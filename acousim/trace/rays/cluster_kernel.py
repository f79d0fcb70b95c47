"""Compiled steps of :mod:`acousim.trace.rays.cluster` (numba; optional: without
numba they run in numpy there, with the same arithmetic in the same order, so the
same clusters and the same sums).

:func:`members`: steps 1 and 2 (the groups, their direction cells and range bins,
each numbered by the rank of its key among the keys present, as ``np.unique``
numbers them); :func:`reflectors`: step 3 (per cluster the summed intensity and
the intensity-weighted means, summed in the contributions' order as
``np.bincount`` sums them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def dense(v):  # pragma: no cover - compiled
    """(ranks (K,), count): each integer of `v` (K,) numbered by its rank among the
    distinct values, ascending (``np.unique``'s inverse)."""
    out = np.empty(v.size, np.int64)
    if v.size == 0:
        return out, 0
    lo, hi = v.min(), v.max()
    span = hi - lo + 1
    if span <= 4 * v.size + 4096:  # a table of the span: no sort
        rank = np.zeros(span, np.int64)
        for x in v:
            rank[x - lo] = 1
        r = -1
        for i in range(span):
            if rank[i]:
                r += 1
            rank[i] = r
        for i in range(v.size):
            out[i] = rank[v[i] - lo]
        return out, r + 1
    order = np.argsort(v)
    r = -1
    for j in range(order.size):
        i = order[j]
        if j == 0 or v[i] != v[order[j - 1]]:
            r += 1
        out[i] = r
    return out, r + 1


@njit(cache=True, nogil=True)
def members(
    first, last, point, receiver, lambert, surface, order, signature, cell_rad, bin_factor, res
):  # pragma: no cover - compiled
    """Steps 1 and 2 of :func:`.cluster.members` for K contributions (path legs
    first, last (K,) m, points (K, 3), receiver (3,), lambert (K,), surface, order
    (K,) int, `signature` (K,) int of their interactions, or None): (the cluster
    of each (K,), the number of clusters); direction cells of `cell_rad` times the
    order, the tail's bins `bin_factor` times the order times `res` (m) long."""
    K = first.size
    total = np.empty(K)
    key = np.empty(K, np.int64)
    for i in range(K):
        total[i] = first[i] + last[i]
        s = -1 if lambert[i] else np.int64(surface[i])
        key[i] = (s + 1) * 64 + order[i]
    group, n_group = dense(key)
    if signature is not None:
        top = signature.max() + 1
        for i in range(K):
            key[i] = group[i] * top + signature[i]
        group, n_group = dense(key)
    tail = False
    for i in range(K):
        tail = tail or lambert[i]
    if tail:
        q = np.empty((K, 3), np.int64)
        widest = 0
        for i in range(K):
            for c in range(3):
                u = (point[i, c] - receiver[c]) / last[i]
                q[i, c] = np.int64(np.round(u / (cell_rad * order[i])))
                widest = max(widest, abs(q[i, c]))
        span = widest * 2 + 1
        for i in range(K):
            cell = ((q[i, 0] * span + q[i, 1]) * span + q[i, 2]) + 1 if lambert[i] else 0
            key[i] = group[i] * (span**3 + 2) + cell
        group, n_group = dense(key)
    start = np.full(n_group, np.inf)
    for i in range(K):
        start[group[i]] = min(start[group[i]], total[i])
    bins = np.empty(K, np.int64)
    for i in range(K):
        width = bin_factor * order[i] * res if lambert[i] else res
        bins[i] = np.int64(math.floor((total[i] - start[group[i]]) / width))
    top = bins.max() + 1
    for i in range(K):
        key[i] = group[i] * top + bins[i]
    return dense(key)


@njit(cache=True, nogil=True)
def reflectors(inv, n, intensity, first, last, point, receiver, departure, order):
    """Step 3 of :func:`.cluster.cluster`: per cluster (n) of the contributions
    ``inv`` (K,): the summed intensity (n,), the intensity-weighted mean path
    length, last leg (n,) (m), direction from the receiver (n, 3), departure (n, 3)
    (both made unit) and order (n,)."""  # pragma: no cover - compiled
    w = np.zeros(n)
    length = np.zeros(n)
    leg = np.zeros(n)
    direction = np.zeros((n, 3))
    dep = np.zeros((n, 3))
    mean_order = np.zeros(n)
    for i in range(inv.size):
        k, p = inv[i], intensity[i]
        w[k] += p
        length[k] += p * (first[i] + last[i])
        leg[k] += p * last[i]
        for c in range(3):
            direction[k, c] += p * ((point[i, c] - receiver[c]) / last[i])
            dep[k, c] += p * departure[i, c]
        mean_order[k] += p * np.float64(order[i])
    out_order = np.empty(n, np.int64)
    for k in range(n):
        length[k] /= w[k]
        leg[k] /= w[k]
        for c in range(3):
            direction[k, c] /= w[k]
            dep[k, c] /= w[k]
        a = math.sqrt(direction[k, 0] ** 2 + direction[k, 1] ** 2 + direction[k, 2] ** 2)
        b = math.sqrt(dep[k, 0] ** 2 + dep[k, 1] ** 2 + dep[k, 2] ** 2)
        for c in range(3):
            direction[k, c] /= a
            dep[k, c] /= b
        out_order[k] = np.int64(np.rint(mean_order[k] / w[k]))
    return w, length, leg, direction, dep, out_order
