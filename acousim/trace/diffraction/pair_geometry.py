"""The geometry of a pair of edges for edge-to-edge diffraction: the pair as the
integral sees it (:class:`PairGeometry`), its elements (:class:`EdgePairElements`),
cylindrical coordinates about an edge and the shortest and longest paths over a
pair.  Below both :mod:`.btm_pairs` (the integral) and :mod:`.btm_pairs_compiled`
(its compiled driver)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from acousim.trace.diffraction.btm import Wedge
from processing.base.kernels import optional_kernel


@dataclass(frozen=True, eq=False)
class EdgePairElements:
    """K elements of the edge-to-edge paths S -> edge 1 -> edge 2 -> R (world frame).

    The path length of an element at R is exact (first_leg_m + second_leg_m); its
    points are means over the element.
    """

    first_point_m: np.ndarray
    """(K, 3) mean point on edge 1, m."""
    point_m: np.ndarray
    """(K, 3) mean point on edge 2, m."""
    first_leg_m: np.ndarray
    """(K,) path length from S over edge 1 to point_m, m."""
    second_leg_m: np.ndarray
    """(K,) |point_m - R|, m."""
    amplitude: np.ndarray
    """(K,) the element's signed impulse amplitude at R (free field ``1/r`` units)."""
    pair: np.ndarray | None = None
    """(K,) int, the pair (of :class:`PairGeometry`) each element belongs to (None: 0)."""

    def __post_init__(self):
        if self.pair is None:
            object.__setattr__(self, "pair", np.zeros(self.amplitude.size, int))

    def __len__(self) -> int:
        return self.amplitude.size

    @staticmethod
    def empty() -> EdgePairElements:
        z3, z = np.zeros((0, 3)), np.zeros(0)
        return EdgePairElements(z3, z3, z, z, z, np.zeros(0, int))


@dataclass(frozen=True, eq=False)
class PairGeometry:
    """N ordered edge pairs that share a plane (world frame, metres)."""

    start1: np.ndarray
    """(N, 3) edge 1's first endpoint, m."""
    end1: np.ndarray
    """(N, 3) edge 1's second endpoint, m."""
    start2: np.ndarray
    """(N, 3) edge 2's first endpoint, m."""
    end2: np.ndarray
    """(N, 3) edge 2's second endpoint, m."""
    face_dir1: np.ndarray
    """(N, 3) unit face direction of edge 1's wedge oriented for the source (air at
    angles 0 .. angle1)."""
    normal1: np.ndarray
    """(N, 3) unit normal of edge 1's oriented wedge, towards the air."""
    face_dir2: np.ndarray
    """(N, 3) unit face direction of edge 2's wedge oriented for the receiver."""
    normal2: np.ndarray
    """(N, 3) unit normal of edge 2's oriented wedge, towards the air."""
    angle1: np.ndarray
    """(N,) open angle of edge 1's wedge, rad."""
    angle2: np.ndarray
    """(N,) open angle of edge 2's wedge, rad."""
    theta12: np.ndarray
    """(N,) the angle of edge 2 about edge 1, rad (0 or the open angle)."""
    theta21: np.ndarray
    """(N,) the angle of edge 1 about edge 2, rad (0 or the open angle)."""
    terms1: np.ndarray
    """(N, 4) weights of the four beta terms of edge 1's wedge (``(R2, 1, 1, R1)``:
    the whole wedge, see :class:`Wedge`)."""
    terms2: np.ndarray
    """(N, 4) weights of the four beta terms of edge 2's wedge."""
    sides: np.ndarray
    """(N,) int, 1 or 2 (see the module docstring)."""

    def __len__(self) -> int:
        return self.angle1.size

    @classmethod
    def of(cls, wedge1: Wedge, wedge2: Wedge, theta_12: float, theta_21: float, sides: int):
        """One pair from two :class:`Wedge`."""

        def terms(w):
            r1, r2 = w.reflection
            return np.array([w.terms if w.terms is not None else (r2, 1.0, 1.0, r1)], float)

        def row(x):
            return np.asarray(x, float)[None]

        return cls(
            row(wedge1.start_m), row(wedge1.end_m), row(wedge2.start_m), row(wedge2.end_m),
            row(wedge1.face_dir), row(wedge1.normal), row(wedge2.face_dir), row(wedge2.normal),
            row(wedge1.angle_rad), row(wedge2.angle_rad), row(theta_12), row(theta_21),
            terms(wedge1), terms(wedge2), np.array([sides], int),
        )  # fmt: skip

    def take(self, keep: np.ndarray) -> PairGeometry:
        """The pairs at `keep` (indices or a mask), with the shortest paths found for
        these (:func:`shortest_paths`), the edges' axes and the compiled integral's
        tables (:mod:`.pairs_compiled`), if any."""
        keep = np.asarray(keep)
        if keep.dtype == bool:  # indices: each field is gathered faster
            keep = np.flatnonzero(keep)
        # (np.take gathers rows much faster than indexing does)
        out = PairGeometry(*(np.take(getattr(self, name), keep, axis=0) for name in _FIELDS))
        memo = self.__dict__.get("_shortest")
        if memo is not None:
            object.__setattr__(out, "_shortest", (memo[0], memo[1][keep], memo[2][keep]))
        memo = self.__dict__.get("_tables")  # the compiled integral's tables
        if memo is not None:
            rows = tuple(np.take(x, keep, axis=0) for x in memo[1])
            object.__setattr__(out, "_tables", (memo[0], rows))
        for key in ("_edge1", "_edge2"):
            axis = self.__dict__.get(key)
            if axis is not None:
                object.__setattr__(out, key, (np.take(axis[0], keep, axis=0), axis[1][keep]))
        return out

    def with_axes(self, edge1, edge2) -> PairGeometry:
        """These pairs, told the (axis (N, 3), length (N,)) of edge 1 and of edge 2
        (as :func:`segment_axes` finds them: e.g. gathered from each edge's own); returns
        self."""
        object.__setattr__(self, "_edge1", edge1)
        object.__setattr__(self, "_edge2", edge2)
        return self

    def edge1(self):
        """(axis (N, 3), length (N,)) of edge 1 (found once: not to be changed)."""
        got = self.__dict__.get("_edge1")
        if got is None:
            got = segment_axes(self.start1, self.end1)
            object.__setattr__(self, "_edge1", got)
        return got

    def edge2(self):
        """(axis (N, 3), length (N,)) of edge 2 (found once: not to be changed)."""
        got = self.__dict__.get("_edge2")
        if got is None:
            got = segment_axes(self.start2, self.end2)
            object.__setattr__(self, "_edge2", got)
        return got


_FIELDS = tuple(f.name for f in fields(PairGeometry))


def segment_axes(start, end):
    """(unit vector (N, 3) from start to end (N, 3), length (N,)) of N segments."""
    length = np.linalg.norm(end - start, axis=1)
    return (end - start) / np.where(length > 0, length, 1.0)[:, None], length


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def cylindrical(p, start, axis, face_dir, normal):
    """(r, theta, z) (N,) of points p (3,) or (N, 3) about N edges; theta in [0, 2 pi)
    from face 1 towards its normal, z along the edge from its start."""
    d = p - start
    z = _dot(d, axis)
    v = d - z[:, None] * axis
    th = np.mod(np.arctan2(_dot(v, normal), _dot(v, face_dir)), 2 * np.pi)
    return np.linalg.norm(v, axis=1), th, z


def _apex(s, r, start, axis, length):
    """First-order apex (K,) of s (K, 3) or (3,) and r (3,) on K edges (z along each
    edge from its start, clipped to it): the point of least |s - x| + |x - r|."""
    ds, dr = s - start, r - start
    zs, zr = _dot(ds, axis), _dot(dr, axis)
    rs = np.linalg.norm(ds - zs[:, None] * axis, axis=1)
    rr = np.linalg.norm(dr - zr[:, None] * axis, axis=1)
    tot = rs + rr
    z = np.where(tot > 0, (rr * zs + rs * zr) / np.where(tot > 0, tot, 1.0), zs)
    return np.clip(z, 0.0, length)


def shortest_paths(pairs: PairGeometry, source, receiver) -> tuple[np.ndarray, np.ndarray]:
    """(z1 at the pair's shortest path, that path's length) (N,) each: the least of
    the convex profile, by bisection on the sign of its slope (60 halvings; compiled
    if numba is installed).  Kept on `pairs` for this source and receiver (the stage
    asks up to four times a pose; :meth:`PairGeometry.take` keeps those of the rows
    taken): the arrays returned are not to be changed."""
    key = (np.asarray(source, float).tobytes(), np.asarray(receiver, float).tobytes())
    memo = pairs.__dict__.get("_shortest")
    if memo is not None and memo[0] == key:
        return memo[1], memo[2]
    z, p = _shortest_paths(pairs, source, receiver)
    object.__setattr__(pairs, "_shortest", (key, z, p))
    return z, p


def _shortest_paths(pairs: PairGeometry, source, receiver) -> tuple[np.ndarray, np.ndarray]:
    kernel = optional_kernel("acousim.trace.diffraction.pair_kernel")
    if kernel is not None:
        out = np.empty((len(pairs), 2))
        kernel.shortest(
            np.asarray(source, float), np.asarray(receiver, float), _edge_table(pairs), out
        )
        return out[:, 0], out[:, 1]
    prof = _Profile(pairs, source, receiver)
    _, length = pairs.edge1()
    k = np.arange(len(pairs))
    lo, hi = np.zeros(len(pairs)), length.copy()
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        up = prof(mid, k)[1] > 0
        lo, hi = np.where(up, lo, mid), np.where(up, mid, hi)
    z = 0.5 * (lo + hi)
    return z, prof(z, k)[0]


def _farthest(pairs: PairGeometry, source, receiver) -> np.ndarray:
    """The longest path (N,) over the ends of both edges (the path is convex in
    (z1, z2): its largest value on the edges is at a pair of ends)."""
    p = pairs
    ends1, ends2 = np.stack([p.start1, p.end1]), np.stack([p.start2, p.end2])  # (2, N, 3)
    m = np.linalg.norm(ends1 - source, axis=-1)  # (2, N)
    n = np.linalg.norm(ends1[:, None] - ends2[None], axis=-1)  # (2, 2, N)
    d = m[:, None] + n + np.linalg.norm(receiver - ends2, axis=-1)[None]
    return np.max(d.reshape(4, len(p)), axis=0, initial=0.0)


@dataclass(frozen=True)
class _Profile:
    """The profile P1(z1) = m + min_z2 (n + l) of N pairs (step 1)."""

    pairs: PairGeometry
    source: np.ndarray
    receiver: np.ndarray

    def __call__(self, z1: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """P1 and dP1/dz1 at z1 (K,) on the edges 1 of pairs k (K,)."""
        p = self.pairs
        ax1, _ = p.edge1()
        ax2, len2 = p.edge2()
        x1 = p.start1[k] + z1[:, None] * ax1[k]
        z2 = _apex(x1, self.receiver, p.start2[k], ax2[k], len2[k])
        x2 = p.start2[k] + z2[:, None] * ax2[k]
        d1, d2 = x1 - self.source, x1 - x2
        m = np.linalg.norm(d1, axis=1)
        n = np.linalg.norm(d2, axis=1)
        value = m + n + np.linalg.norm(self.receiver - x2, axis=1)
        slope = _dot(d1, ax1[k]) / np.maximum(m, 1e-300) + _dot(d2, ax1[k]) / np.maximum(n, 1e-300)
        return value, slope


def _edge_table(pairs: PairGeometry) -> np.ndarray:
    """(N, 14): start1, axis1, length1, start2, axis2, length2 of each pair."""
    ax1, len1 = pairs.edge1()
    ax2, len2 = pairs.edge2()
    return np.column_stack([pairs.start1, ax1, len1, pairs.start2, ax2, len2])


def _levels(prof: _Profile, k, z_apex, z_end, p_min, level, newton=30):
    """z (K,) where the profile of pair k reaches p_min + level between its apex and
    z_end (Newton from z_end: monotone on a convex function; clipped)."""
    z = z_end.copy()
    target = p_min + level
    lo, hi = np.minimum(z_apex, z_end), np.maximum(z_apex, z_end)
    for _ in range(newton):
        value, slope = prof(z, k)
        gap = value - target
        safe = np.abs(slope) > 1e-12
        z = np.clip(np.where(safe, z - gap / np.where(safe, slope, 1.0), z), lo, hi)
        if np.all(np.abs(gap) < 1e-12 + 1e-9 * level):
            break
    return np.where(level <= 0, z_apex, z)
