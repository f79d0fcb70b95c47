"""The compiled edge-to-edge integral's driver: the tables of
:func:`acousim.trace.diffraction.pair_kernel.pair_bins` built from the pairs' geometry, its
bins read back as :class:`acousim.trace.diffraction.pairs.EdgePairElements` (compiled
too, :mod:`.bins_kernel`, where numba is; the numpy form of the same steps is in
:mod:`acousim.trace.diffraction.pairs`)."""

from __future__ import annotations

import numpy as np

from acousim.trace.diffraction.pair_geometry import (
    EdgePairElements,
    PairGeometry,
    _farthest,
    cylindrical,
    shortest_paths,
)
from processing.base.kernels import optional_kernel

__all__ = ["compiled_elements", "fine_live"]


def fine_live(live, n_bins: int, width: float) -> np.ndarray:
    """(N, n_bins) uint8: the bins of `width` (m) that overlap a live bin of `live`
    (mask (N, B), width (m))."""
    mask, w = live
    b = np.arange(n_bins)
    lo = np.minimum((b * width / w).astype(np.int64), mask.shape[1] - 1)
    hi = np.minimum(((b + 1) * width / w * (1 - 1e-12)).astype(np.int64), mask.shape[1] - 1)
    return (mask[:, lo] | mask[:, hi]).astype(np.uint8)


def compiled_elements(
    kernel, pairs: PairGeometry, source, receiver, limits, workers=None
) -> EdgePairElements:
    """:func:`pair_elements` by the compiled kernel; limits: ((step, longest path,
    excess kept, bin width) in metres and the halvings of the first step (edge 1's,
    edge 2's), the live bins or None); workers: None, or an object with ``threads``
    and ``map(fn, items)`` (the tracer's :class:`~acousim.trace.world.embree.RayCaster`)
    to share the pairs among its threads (the kernel releases the GIL; each pair's
    bins are the same whichever thread fills them)."""
    (step_m, max_path_m, max_excess_m, width, refine), wanted = limits
    p = pairs
    n = len(p)
    geo, consts, live = _tables(p, source, receiver, (max_path_m, max_excess_m))
    nb = int(np.ceil(max_excess_m / width)) + 2
    longest = float(np.max(max_path_m))  # the kernel reads geo's column 24
    cfg = np.array([step_m, step_m, *refine, max_excess_m, longest, width, nb], float)
    idx = np.flatnonzero(live)
    acc = np.zeros((idx.size, nb, 9))
    count = np.zeros((idx.size, nb), np.int64)
    mask = np.ones((n, nb), np.uint8) if wanted is None else fine_live(wanted, nb, width)
    tables = (np.ascontiguousarray(x[idx]) for x in (geo, consts, mask))
    g, c, m = tables
    _run(kernel, (source, receiver, g, c, cfg, acc, count, m), workers)
    reader = optional_kernel("acousim.trace.diffraction.bins_kernel", "read_bins")
    if reader is not None:  # the same elements, compiled
        n_max = count.size
        out = (np.empty((n_max, 3)), np.empty((n_max, 3)), *(np.empty(n_max) for _ in range(3)))
        out += (np.empty(n_max, idx.dtype),)
        got = reader(count, acc, np.asarray(receiver, float), idx, out)
        if got == 0:
            return EdgePairElements.empty()
        return EdgePairElements(*(x[:got] for x in out))
    k, b = np.nonzero(count)
    if k.size == 0:
        return EdgePairElements.empty()
    a = acc[k, b]
    wsum = np.where(a[:, 1] > 0, a[:, 1], 1.0)
    length = a[:, 2] / wsum
    q1, q2 = a[:, 3:6] / wsum[:, None], a[:, 6:9] / wsum[:, None]
    second = np.linalg.norm(q2 - receiver, axis=1)
    return EdgePairElements(q1, q2, length - second, second, a[:, 0], idx[k])


def _tables(pairs: PairGeometry, source, receiver, reach) -> tuple:
    """(geo (N, 25), consts (N, 6, 4), live (N,)) of :func:`pair_bins` for every pair
    (reach: the longest path kept and the excess kept, m).  Kept on `pairs` for
    this source, receiver and reach when the longest path is one number (the
    stage's coarse and fine passes ask for the same rows: :meth:`PairGeometry.take`
    keeps those of the rows taken); the arrays returned are not to be changed."""
    max_path_m, max_excess_m = reach
    key = None
    if np.ndim(max_path_m) == 0:
        key = (
            np.asarray(source, float).tobytes(),
            np.asarray(receiver, float).tobytes(),
            float(max_path_m),
            float(max_excess_m),
        )
        memo = pairs.__dict__.get("_tables")
        if memo is not None and memo[0] == key:
            return memo[1]
    got = _new_tables(pairs, source, receiver, reach)
    if key is not None:
        object.__setattr__(pairs, "_tables", (key, got))
    return got


def _new_tables(pairs: PairGeometry, source, receiver, reach) -> tuple:
    """:func:`_tables` (see there), computed."""
    max_path_m, max_excess_m = reach
    p = pairs
    n = len(p)
    ax1, len1 = p.edge1()
    ax2, len2 = p.edge2()
    z_apex, p_min = shortest_paths(p, source, receiver)
    rs, ts, zs = cylindrical(source, p.start1, ax1, p.face_dir1, p.normal1)
    rr, tr, zr = cylindrical(receiver, p.start2, ax2, p.face_dir2, p.normal2)
    nu1, nu2 = np.pi / p.angle1, np.pi / p.angle2
    far = _farthest(p, source, receiver)
    geo = np.column_stack(
        [p.start1, ax1, len1, p.start2, ax2, len2, nu1, nu2, rs, zs, rr, zr, p.sides,
         (far - p_min > max_excess_m).astype(float), p_min, z_apex,
         np.broadcast_to(max_path_m, (n,))]
    )  # fmt: skip
    consts = np.empty((n, 6, 4))
    phi1 = np.pi + np.stack([ts + p.theta12, ts - p.theta12, -ts + p.theta12, -ts - p.theta12], 1)
    consts[:, 0], consts[:, 1], consts[:, 2] = (
        np.sin(nu1[:, None] * phi1),
        np.cos(nu1[:, None] * phi1),
        p.terms1,
    )
    phi2 = np.pi + np.stack([p.theta21 + tr, p.theta21 - tr, -p.theta21 + tr, -p.theta21 - tr], 1)
    half = nu2[:, None] * phi2 / 2
    sh, ch = np.sin(half), np.cos(half)
    flip = sh < 0
    consts[:, 3], consts[:, 4], consts[:, 5] = (
        np.where(flip, -sh, sh),
        np.where(flip, -ch, ch),
        p.terms2,
    )
    live = (rs > 0) & (rr > 0) & (tr <= p.angle2) & (ts <= p.angle1)
    return geo, consts, live


def _run(kernel, args, workers) -> None:
    """``kernel.pair_bins`` on every pair of args (source, receiver, geo, consts,
    cfg, acc, count, live), the pairs shared among the workers' threads
    (:func:`compiled_elements`): ordered by their live bins (a measure of their
    work) and dealt out in turn, each thread filling its own pairs' rows of the
    same acc and count (each pair's bins are the same whichever thread fills them)."""
    source, receiver, g, c, cfg, acc, count, m = args
    n = g.shape[0]
    parts = 1 if workers is None else min(int(workers.threads), n)
    if parts < 2:
        kernel.pair_bins(source, receiver, g, c, cfg, (acc, count), m, np.arange(n))
        return
    order = np.argsort(-m.sum(axis=1), kind="stable")
    shares = [order[i::parts] for i in range(parts)]

    def one(share):
        kernel.pair_bins(source, receiver, g, c, cfg, (acc, count), m, share)

    workers.map(one, shares)
