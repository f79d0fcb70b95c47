"""The edge pairs out of reach (every path over them longer than ``max_path_m``)
left out of edge to edge before their bounds and rays: the pair table's distance
between two edges against a brute-force one, the pairs left out against their own
integrals (no element within ``max_path_m``), and the stage's paths with and
without the cut (the same numbers), on a pose traced fresh and after others."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from acousim.scene.model import Diffraction
from acousim.trace.diffraction import edge_to_edge as e2e
from acousim.trace.diffraction.pairs import pair_elements
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions, diffract
from acousim.trace.world.edges import find_edges
from acousim.trace.world.embree import RayCaster
from tests.acousim.trace.diffraction.test_edge_to_edge import plane_ids
from tests.acousim.trace.diffraction.test_pair_selection import EMITTER, RECEIVER, room_objects

#: paths over the door's far edges are longer, over the box's and the plate's shorter
MAX_PATH_M = 3.2


def _brute_distance(a1, b1, a2, b2, n=801) -> float:
    """Least distance between two segments over n x n points of each (an upper
    bound, within half a step of either segment of the true one)."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    p, q = a1 + t * (b1 - a1), a2 + t * (b2 - a2)
    return float(np.sqrt(((p[:, None, :] - q[None, :, :]) ** 2).sum(axis=2)).min())


def test_the_edges_distance_is_a_lower_bound_close_to_the_brute_force_one():
    rng = np.random.default_rng(7)
    cases = [tuple(rng.normal(size=(4, 3))) for _ in range(12)]
    # meeting at a corner, crossing, parallel, in one plane apart
    x, y, o = np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.zeros(3)
    z = np.array([0, 0, 1.0])
    cases += [(o, x, o, y), (-x, x, -y, y), (o, x, y, x + y), (o, x, 2 * x + y, 3 * x + 2 * y)]
    # antiparallel 1 apart, overlapping; nearly parallel, crossing in the middle
    cases += [(o, x, 2 * x + z, -x + z), (-x - 1e-4 * y, x + 1e-4 * y, -x + 1e-4 * y, x - 1e-4 * y)]
    start = np.array([c[k] for c in cases for k in (0, 2)])
    end = np.array([c[k] for c in cases for k in (1, 3)])
    i, j = np.arange(0, 2 * len(cases), 2), np.arange(1, 2 * len(cases), 2)
    gap = e2e._segments_apart(start, end, i, j)
    for k, (a1, b1, a2, b2) in enumerate(cases):
        brute = _brute_distance(a1, b1, a2, b2)
        step = max(np.linalg.norm(b1 - a1), np.linalg.norm(b2 - a2)) / 800
        assert gap[k] <= brute + 1e-12
        assert gap[k] >= brute - step
    assert gap[12] == 0.0 and gap[13] == 0.0
    assert 1 - 1e-8 < gap[14] <= 1.0 and 1 - 1e-8 < gap[16] <= 1.0
    # all but parallel, crossing (at 1e-4 rad): the ends are 1e-4 apart, the lines meet
    assert gap[17] == 0.0
    assert np.sqrt(2.0) - 1e-8 < gap[15] <= np.sqrt(2.0)  # less a rounding margin


@pytest.fixture(scope="module")
def room():
    mesh = room_objects()
    return mesh, RayCaster(mesh.triangles, 1)


def _geometry(mesh) -> DiffractingGeometry:
    return DiffractingGeometry(
        find_edges(mesh), np.ones(len(mesh.faces)), face_plane=plane_ids(mesh)
    )


def _options(**kw) -> DiffractionOptions:
    return DiffractionOptions(max_path_m=MAX_PATH_M, settings=Diffraction(order=2), **kw)


def _everything(monkeypatch):
    """The cut undone: every edge and pair within reach."""
    monkeypatch.setattr(e2e, "_reach", lambda ctx, shortest_m: np.ones(np.shape(shortest_m), bool))


def test_the_pairs_left_out_have_no_path_within_reach(room, monkeypatch):
    mesh, caster = room
    geometry = _geometry(mesh)
    ctx = StageContext(geometry, caster, EMITTER, RECEIVER, _options())
    kept = e2e.candidate_pairs(ctx)[0]
    with monkeypatch.context() as m:
        _everything(m)
        ctx = StageContext(geometry, caster, EMITTER, RECEIVER, _options())
        every = e2e.candidate_pairs(ctx)[0]
    assert 20 < len(kept) < len(every)
    # the rows of the pairs kept are those of every pair, less the others
    key = np.column_stack([every.start1, every.end1, every.start2, every.end2])
    mine = np.column_stack([kept.start1, kept.end1, kept.start2, kept.end2])
    left = ~(key[:, None, :] == mine[None, :, :]).all(axis=2).any(axis=1)
    assert left.sum() == len(every) - len(kept)
    # their own integrals (in numpy): no element within max_path_m
    out = every.take(np.flatnonzero(left))
    el = pair_elements(out, EMITTER, RECEIVER, max_path_m=MAX_PATH_M, use_kernel=False)
    assert len(el) == 0
    # while the same pairs have paths within twice the reach
    el = pair_elements(out, EMITTER, RECEIVER, max_path_m=2 * MAX_PATH_M, use_kernel=False)
    assert len(el) > 0


def _paths(geometry, caster, options, emitter=EMITTER):
    d = diffract(geometry, caster, emitter, RECEIVER, options)
    return [
        np.asarray(getattr(d, f.name))
        for f in dataclasses.fields(d)
        if getattr(d, f.name) is not None
    ]


@pytest.mark.parametrize("select", [True, False])
def test_the_stage_is_the_same_with_the_pairs_out_of_reach_left_out(room, monkeypatch, select):
    mesh, caster = room
    options = _options(floor_level=1e-5 if select else 0.0, select_pairs=select)
    with monkeypatch.context() as m:
        _everything(m)
        want = _paths(_geometry(mesh), caster, options)
    assert len(want[0]) > 100
    geometry = _geometry(mesh)
    # fresh, and after other poses (the pair table and its edges' distances kept)
    fresh = _paths(geometry, caster, options)
    for dz in (0.05, 0.1):
        _paths(geometry, caster, options, EMITTER + [0.0, 0.0, dz])
    warm = _paths(geometry, caster, options)
    for got in (fresh, warm):
        assert len(got) == len(want)
        for a, b in zip(got, want):
            assert a.shape == b.shape and np.array_equal(a, b)


def test_the_edges_distance_goes_with_the_geometry(room):
    mesh, caster = room
    geometry = _geometry(mesh)
    ctx = StageContext(geometry, caster, EMITTER, RECEIVER, _options())
    table = e2e._pair_table(ctx)
    moved = mesh.copy()
    moved.apply_scale(2.0)
    other = _geometry(moved)
    assert "pair_table" not in other.memo  # a geometry of its own: its own table
    table2 = e2e._pair_table(StageContext(other, caster, EMITTER, RECEIVER, _options()))
    assert table2 is not table and table2.i.size == table.i.size
    edges = other.edges
    assert np.array_equal(
        table2.gap, e2e._segments_apart(edges.start_m, edges.end_m, table2.i, table2.j)
    )
    # twice the size: each distance twice (less the rounding margin)
    assert np.sort(table2.gap) == pytest.approx(2 * np.sort(table.gap), abs=1e-7)
    assert table.gap.max() > 0.5


def test_the_pairs_are_the_seen_ones_whatever_the_order_of_the_filters(room):
    """The pairs in view found with the probe rays cast last (for the pairs' edges
    left) are those found with them cast first for every edge (as before), within
    reach."""
    mesh, caster = room
    geometry = _geometry(mesh)
    ctx = StageContext(geometry, caster, EMITTER, RECEIVER, _options())
    got = e2e._pairs_in_view(ctx)
    # the filters in the order before: seen first (every convex edge near enough)
    ctx = StageContext(geometry, caster, EMITTER, RECEIVER, _options())
    pose = e2e.pose_edges(ctx)
    keep1 = pose.convex_e & (pose.dist_e < MAX_PATH_M)
    keep2 = pose.convex_r & (pose.dist_r < MAX_PATH_M)
    idx1, idx2 = np.flatnonzero(keep1), np.flatnonzero(keep2)
    seen1, seen2 = e2e.probe_seen(ctx, (0, idx1), (1, idx2))
    keep1[idx1], keep2[idx2] = seen1.any(axis=1), seen2.any(axis=1)
    table = e2e._pair_table(ctx)
    at = np.flatnonzero(keep1[table.i] & keep2[table.j])
    at = at[table.over_a_face(ctx, pose.wedge_e, at)]
    i, j = table.i[at], table.j[at]
    # within reach: a path over the pair (on a grid of points along each edge) no
    # longer than max_path_m, so its shortest path too
    edges = geometry.edges
    t = np.linspace(0.0, 1.0, 201)[:, None]
    shortest = []
    for a, b in zip(i, j):
        p = edges.start_m[a] + t * (edges.end_m[a] - edges.start_m[a])
        q = edges.start_m[b] + t * (edges.end_m[b] - edges.start_m[b])
        legs = np.linalg.norm(p[:, None] - q[None], axis=2)
        legs += np.linalg.norm(p - EMITTER, axis=1)[:, None]
        shortest.append((legs + np.linalg.norm(q - RECEIVER, axis=1)[None]).min())
    near = np.array(shortest) <= MAX_PATH_M
    assert 20 < near.sum() < near.size
    assert set(at[near]) <= set(got) <= set(at)
    assert len(got) < near.size  # some left out


def test_the_pairs_of_some_edges_are_those_of_a_mask(room):
    mesh, caster = room
    geometry = _geometry(mesh)
    table = e2e._pair_table(StageContext(geometry, caster, EMITTER, RECEIVER, _options()))
    keep = np.random.default_rng(3).random(len(geometry.edges)) < 0.3
    want = np.flatnonzero(keep[table.i])
    assert want.size > 10
    assert np.array_equal(table.of_edges(np.flatnonzero(keep)), want)
    assert table.of_edges(np.zeros(0, int)).size == 0
