"""The compiled bound and estimate of edge pairs (:mod:`acousim.trace.diffraction.bound_kernel`)
against the numpy versions they replace (:func:`acousim.trace.diffraction.pair_bound.pair_bound`
and :func:`~acousim.trace.diffraction.pair_bound.pair_estimate` with ``use_kernel=False``, a
second implementation of the same formulas on whole arrays): equal within rounding
on random pairs (parallel edges, shared corners, zero term weights, thin plates
among them), at a singular beta term, and on a scene's candidate pairs, where the
pairs each keeps at the stage's floor are the same.  That the bound bounds the full
integral is ``tests/acousim/trace/diffraction/test_pair_selection.py``'s (which runs the kernel)."""

from __future__ import annotations

import numpy as np
import pytest

from acousim.scene.model import Diffraction
from acousim.trace.diffraction.edge_to_edge import candidate_pairs
from acousim.trace.diffraction.pair_bound import ESTIMATE_MARGIN, pair_bound, pair_estimate
from acousim.trace.diffraction.pair_geometry import PairGeometry
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions
from acousim.trace.world.edges import find_edges
from acousim.trace.world.embree import RayCaster
from tests.acousim.trace.diffraction.test_edge_to_edge import plane_ids
from tests.acousim.trace.diffraction.test_pair_selection import (
    EMITTER,
    FLOOR,
    RECEIVER,
    room_objects,
)

pytest.importorskip("numba")

BIN_M = 0.25e-3
LIMITS = dict(max_excess_m=0.05, max_path_m=8.0, bin_m=BIN_M)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _random_pairs(rng, n: int) -> PairGeometry:
    """n pairs of random edges 0.3-3 m away (0.01-2 m long), with oriented wedges;
    a quarter with edge 2 parallel to edge 1, a quarter sharing edge 1's end."""
    start1 = rng.uniform(-2, 2, (n, 3)) + [2.0, 0, 0]
    ax1 = _unit(rng.normal(size=(n, 3)))
    end1 = start1 + rng.uniform(0.01, 2, (n, 1)) * ax1
    start2 = start1 + rng.uniform(-0.5, 0.5, (n, 3))
    ax2 = _unit(rng.normal(size=(n, 3)))
    q = n // 4
    ax2[:q] = ax1[:q]  # parallel
    start2[q : 2 * q] = end1[q : 2 * q]  # a shared corner
    end2 = start2 + rng.uniform(0.01, 2, (n, 1)) * ax2

    def wedge(axis):
        face = _unit(np.cross(axis, rng.normal(size=(n, 3))))
        return face, np.cross(axis, face)

    fd1, nm1 = wedge(ax1)
    fd2, nm2 = wedge(ax2)
    angle1, angle2 = rng.uniform(np.pi, 2 * np.pi, n), rng.uniform(np.pi, 2 * np.pi, n)
    angle1[::7] = 2 * np.pi  # thin plates
    th12 = np.where(rng.random(n) < 0.5, 0.0, angle1)
    th21 = np.where(rng.random(n) < 0.5, 0.0, angle2)
    terms1 = rng.uniform(0.2, 1, (n, 4)) * (rng.random((n, 4)) < 0.8)
    terms2 = rng.uniform(0.2, 1, (n, 4)) * (rng.random((n, 4)) < 0.8)
    sides = rng.integers(1, 3, n)
    return PairGeometry(
        start1, end1, start2, end2, fd1, nm1, fd2, nm2,
        angle1, angle2, th12, th21, terms1, terms2, sides,
    )  # fmt: skip


def _agree(a: np.ndarray, b: np.ndarray, rtol: float):
    """The same zeros and infinities, the rest equal within rtol."""
    np.testing.assert_array_equal(a == 0, b == 0)
    np.testing.assert_array_equal(np.isinf(a), np.isinf(b))
    assert not np.isnan(a).any() and not np.isnan(b).any()
    ok = np.isfinite(a) & (a > 0)
    np.testing.assert_allclose(a[ok], b[ok], rtol=rtol, atol=0)


def test_the_kernel_agrees_with_numpy_on_random_pairs():
    rng = np.random.default_rng(23)
    pairs = _random_pairs(rng, 400)
    for source, receiver in ((EMITTER, RECEIVER), (rng.normal(size=3), rng.normal(size=3))):
        for excess_m, max_path_m in ((0.05, 8.0), (3.0, 20.0), (1.0, 3.0)):
            limits = dict(LIMITS, max_excess_m=excess_m, max_path_m=max_path_m)
            fast = pair_bound(pairs, source, receiver, **limits)
            plain = pair_bound(pairs, source, receiver, use_kernel=False, **limits)
            assert (fast > 0).sum() > 10
            _agree(fast, plain, 1e-9)
        fast = pair_estimate(pairs, source, receiver, bin_m=BIN_M)
        plain = pair_estimate(pairs, source, receiver, bin_m=BIN_M, use_kernel=False)
        _agree(fast, plain, 1e-9)


def test_the_kernel_agrees_on_a_singular_beta_and_at_a_corner():
    """The source on face 1's plane extended beyond edge 1 (theta = pi: a singular
    beta term, the bound is inf) and edge 2 starting where edge 1 ends (n = 0 at the
    shortest path)."""
    s1, e1 = np.array([[1.0, -0.5, 0.0]]), np.array([[1.0, 0.5, 0.0]])
    s2, e2 = e1, np.array([[1.0, 0.5, 0.6]])
    x, z = np.array([[1.0, 0, 0]]), np.array([[0, 0, 1.0]])
    pairs = PairGeometry(
        s1, e1, s2, e2, z, x, -x, z, np.array([1.5 * np.pi]), np.array([1.5 * np.pi]),
        np.array([0.0]), np.array([0.0]), np.ones((1, 4)), np.ones((1, 4)), np.array([1]),
    )  # fmt: skip
    source, receiver = np.array([0.2, 0.1, 0.05]), np.array([0.0, 0.3, 0.2])
    in_plane = np.array([1.0, 0.1, -0.3])
    for s in (source, in_plane):
        fast = pair_bound(pairs, s, receiver, **LIMITS)
        _agree(fast, pair_bound(pairs, s, receiver, use_kernel=False, **LIMITS), 1e-12)
        fast = pair_estimate(pairs, s, receiver, bin_m=BIN_M)
        plain = pair_estimate(pairs, s, receiver, bin_m=BIN_M, use_kernel=False)
        _agree(fast, plain, 1e-12)
    assert np.isinf(pair_bound(pairs, in_plane, receiver, **LIMITS)[0])


def test_the_kernel_keeps_the_same_pairs_of_a_scene():
    mesh = room_objects()
    geometry = DiffractingGeometry(
        find_edges(mesh), np.ones(len(mesh.faces)), face_plane=plane_ids(mesh)
    )
    ctx = StageContext(
        geometry,
        RayCaster(mesh.triangles, 1),
        EMITTER,
        RECEIVER,
        DiffractionOptions(max_path_m=8.0, settings=Diffraction(order=2)),
    )
    rows, _, _ = candidate_pairs(ctx)
    fast = pair_bound(rows, EMITTER, RECEIVER, **LIMITS)
    plain = pair_bound(rows, EMITTER, RECEIVER, use_kernel=False, **LIMITS)
    _agree(fast, plain, 1e-9)
    np.testing.assert_array_equal(fast >= FLOOR, plain >= FLOOR)
    sub = rows.take(np.flatnonzero(fast >= FLOOR))
    assert 10 < len(sub) < len(rows)
    fast = pair_estimate(sub, EMITTER, RECEIVER, bin_m=BIN_M)
    plain = pair_estimate(sub, EMITTER, RECEIVER, bin_m=BIN_M, use_kernel=False)
    _agree(fast, plain, 1e-12)
    np.testing.assert_array_equal(ESTIMATE_MARGIN * fast >= FLOOR, ESTIMATE_MARGIN * plain >= FLOOR)
