"""The diffracting edges of a prepared world (acousim.trace.world.edges.world_edges, found
from the world's own faces, planes and edge table; collinear pieces joined by
DiffractingGeometry.of), against references written here: the 12 edges of a box of
known size, the edges of prisms of known interior angles, the rims of open and
non-manifold sheets, and a plain dictionary-of-edges finder on the bundled scenes."""

import dataclasses
import itertools
from collections import defaultdict

import numpy as np
import pytest
import trimesh

from acousim.scene import load_scene
from acousim.scene.model import MeshItem
from acousim.trace.diffraction.setup import DiffractingGeometry
from acousim.trace.world.build import build_world
from acousim.trace.world.edges import world_edges
from acousim.trace.world.mesh_index import _sorted_codes
from tests import REPO

SCENES = REPO / "scenes"
TWO_PI = 2 * np.pi


def _world(*meshes):
    scene = load_scene(SCENES / "shoebox.toml")
    return build_world(dataclasses.replace(scene, meshes=tuple(MeshItem(m) for m in meshes)))


def _edges(*meshes):
    return DiffractingGeometry.of(_world(*meshes)).edges


def _segments(start, end, digits=9):
    """Segments as a sorted list of rounded (endpoint, endpoint) tuples, either way."""
    out = []
    for a, b in zip(np.round(start, digits) + 0.0, np.round(end, digits) + 0.0):
        out.append(tuple(sorted([tuple(a), tuple(b)])))
    return sorted(out)


def _open(angle):
    """The larger open angle of an edge's two sides (rad)."""
    return np.maximum(angle, TWO_PI - angle)


def _check_frames(edges):
    """face_dir and other_dir are unit, perpendicular to the edge; normal is
    perpendicular to face_dir; the angle from face_dir to other_dir turning towards
    normal is angle_rad."""
    axis = edges.end_m - edges.start_m
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    for d in (edges.face_dir, edges.other_dir, edges.normal):
        assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert np.allclose(np.einsum("ij,ij->i", edges.face_dir, axis), 0, atol=1e-12)
    assert np.allclose(np.einsum("ij,ij->i", edges.other_dir, axis), 0, atol=1e-12)
    assert np.allclose(np.einsum("ij,ij->i", edges.face_dir, edges.normal), 0, atol=1e-12)
    turned = (
        np.cos(edges.angle_rad)[:, None] * edges.face_dir
        + np.sin(edges.angle_rad)[:, None] * edges.normal
    )
    assert np.allclose(turned, edges.other_dir, atol=1e-9)


def _box_reference(size):
    """The 12 edges of an axis-aligned box centred on the origin."""
    half = np.asarray(size, float) / 2
    start, end = [], []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        for si, sj in itertools.product((-1, 1), repeat=2):
            p = np.zeros(3)
            p[i], p[j] = si * half[i], sj * half[j]
            a, b = p.copy(), p.copy()
            a[k], b[k] = -half[k], half[k]
            start.append(a)
            end.append(b)
    return _segments(np.array(start), np.array(end))


@pytest.mark.parametrize("subdivisions", [0, 2])
def test_a_box_has_its_twelve_right_angled_edges(subdivisions):
    size = (0.3, 0.5, 0.7)
    box = trimesh.creation.box(extents=size)
    for _ in range(subdivisions):
        box = box.subdivide()
    edges = _edges(box)
    assert _segments(edges.start_m, edges.end_m) == _box_reference(size)
    assert np.allclose(_open(edges.angle_rad), 1.5 * np.pi)
    _check_frames(edges)
    # each edge's normal is one of its two faces': an axis perpendicular to it
    axis = np.abs(edges.end_m - edges.start_m) > 1e-9
    n = np.abs(edges.normal)
    assert np.allclose(n.max(axis=1), 1.0) and not (axis & (n > 0.5)).any()
    # face_dir points into face 1: the edge's midpoint moved along it stays on the box
    mid = (edges.start_m + edges.end_m) / 2 + 0.01 * edges.face_dir
    assert np.all(np.abs(mid) <= np.asarray(size) / 2 + 1e-12)
    assert np.all(edges.faces >= 0)


def _prism(section, height):
    """A closed prism over the polygon `section` (n, 2), counter-clockwise, from
    z = 0 to `height`, its caps fanned from their first vertex."""
    n = len(section)
    v = np.vstack(
        [np.column_stack([section, np.zeros(n)]), np.column_stack([section, np.full(n, height)])]
    )
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces += [[i, j, n + j], [i, n + j, n + i]]
    for i in range(1, n - 1):
        faces += [[0, i + 1, i], [n, n + i, n + i + 1]]
    return trimesh.Trimesh(v, faces, process=False)


def _interior_angles(section):
    p = np.asarray(section, float)
    out = []
    for i in range(len(p)):
        a, b = p[i - 1] - p[i], p[(i + 1) % len(p)] - p[i]
        turn = np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b)  # from b to a, counter-clockwise
        out.append(np.mod(-turn, TWO_PI))
    return np.array(out)


@pytest.mark.parametrize(
    "section",
    [
        [[0, 0], [1, 0], [0, np.sqrt(3)]],  # 90, 30 and 60 degrees
        [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]],  # an L: one inside corner
    ],
)
def test_a_prism_has_its_edges_of_known_angles(section):
    height = 0.8
    section = np.asarray(section, float)
    edges = _edges(_prism(section, height))
    n = len(section)
    interior = _interior_angles(section)
    assert np.isclose(interior.sum(), (n - 2) * np.pi)  # the reference itself
    # along z: the n vertical edges, the air's angle 2 pi minus the interior one
    vertical = np.abs(edges.end_m[:, 2] - edges.start_m[:, 2]) > 1e-9
    assert vertical.sum() == n
    at = np.round(edges.start_m[vertical, :2], 9)
    for corner, inner in zip(section, interior):
        k = np.flatnonzero(np.all(np.isclose(at, corner), axis=1))
        assert k.size == 1
        open_angle = edges.angle_rad[vertical][k[0]]
        assert np.isclose(min(open_angle, TWO_PI - open_angle), min(inner, TWO_PI - inner))
    # the caps' outlines: 2 n edges of right angles, of the sides' lengths
    cap = ~vertical
    side = np.linalg.norm(np.roll(section, -1, axis=0) - section, axis=1)
    assert np.allclose(np.sort(edges.length_m[cap]), np.sort(np.repeat(side, 2)))
    assert np.allclose(_open(edges.angle_rad[cap]), 1.5 * np.pi)
    _check_frames(edges)


def test_rims_of_an_open_plate_and_of_fins_on_one_edge():
    plate = trimesh.Trimesh([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    edges = _edges(plate)
    assert _segments(edges.start_m, edges.end_m) == _segments(
        np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], float),
        np.array([[2, 0, 0], [2, 1, 0], [0, 1, 0], [0, 0, 0]], float),
    )
    assert np.allclose(edges.angle_rad, TWO_PI) and np.all(edges.faces[:, 1] == -1)
    assert np.allclose(edges.face_dir, edges.other_dir)
    _check_frames(edges)
    # three fins on the x axis (an edge of three faces, non-manifold): not an edge;
    # each fin keeps its three other sides as rims
    fins = []
    for turn in (0.0, 2.0, 4.0):
        d = np.array([0.0, np.cos(turn), np.sin(turn)])
        v = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0] + d, d])
        fins.append(trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]]))
    edges = _edges(trimesh.util.concatenate(fins))
    on_axis = np.all(np.abs(edges.start_m[:, 1:]) < 1e-9, axis=1) & np.all(
        np.abs(edges.end_m[:, 1:]) < 1e-9, axis=1
    )
    assert len(edges) == 9 and not on_axis.any()
    assert np.allclose(edges.angle_rad, TWO_PI) and np.allclose(edges.length_m, 1.0)


def test_meshes_that_share_vertices_share_their_edges():
    """Two sheets given as two meshes, meeting at a right angle along x: one edge of
    90 / 270 degrees between them (their vertices are merged), and six rims."""
    floor = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    wall = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 1, 2], [0, 2, 3]])
    edges = _edges(floor, wall)
    assert len(edges) == 7
    shared = edges.faces[:, 1] >= 0
    assert shared.sum() == 1
    assert _segments(edges.start_m[shared], edges.end_m[shared]) == [((0, 0, 0), (1, 0, 0))]
    assert np.isclose(_open(edges.angle_rad[shared])[0], 1.5 * np.pi)
    assert np.allclose(edges.angle_rad[~shared], TWO_PI)


def test_a_sheet_folded_onto_itself_keeps_its_fold():
    """Two faces on one plane, on one side of their common edge: a thin double sheet
    whose fold is a knife edge (open angle 2 pi on the side of the air)."""
    v = [[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, 0.5, 0]]
    sheet = trimesh.Trimesh(v, [[0, 1, 2], [0, 1, 3]], process=False)
    edges = world_edges(_world(sheet))
    fold = edges.faces[:, 1] >= 0
    assert fold.sum() == 1
    assert np.isclose(_open(edges.angle_rad[fold])[0], TWO_PI, atol=1e-6)


def _into(a, b, c):
    """The unit vector from the line a-b towards c, perpendicular to it."""
    axis = (b - a) / np.linalg.norm(b - a)
    d = (c - a) - ((c - a) @ axis) * axis
    return d / np.linalg.norm(d)


def _reference_edges(world, min_turn_deg=30.0):
    """A plain finder: every edge (vertex pair, positions rounded to 1e-8 m as trimesh
    merges vertices) with its faces in a dictionary; rims (one face) and pairs whose
    face normals turn by more than min_turn_deg (open angle from the third vertices)."""
    faces_of = defaultdict(list)
    key = lambda p: tuple(np.round(p * 1e8).astype(np.int64))  # noqa: E731
    for f, tri in enumerate(world.triangles):
        for i in range(3):
            a, b = tri[i], tri[(i + 1) % 3]
            faces_of[tuple(sorted([key(a), key(b)]))].append((f, a, b, tri[(i + 2) % 3]))
    out = []
    for group in faces_of.values():
        if len(group) == 1:
            _, a, b, _ = group[0]
            out.append((tuple(sorted([tuple(np.round(a, 7)), tuple(np.round(b, 7))])), TWO_PI))
        elif len(group) == 2:
            (f1, a, b, c1), (f2, _, _, c2) = group
            d1, d2 = _into(a, b, c1), _into(a, b, c2)
            n1 = world.normals[f1]
            angle = np.mod(np.arctan2(d2 @ n1, d2 @ d1), TWO_PI)
            if abs(angle - np.pi) > np.deg2rad(min_turn_deg):
                seg = tuple(sorted([tuple(np.round(a, 7)), tuple(np.round(b, 7))]))
                out.append((seg, round(float(_open(angle)), 6)))
    return sorted((s, round(float(a), 6)) for s, a in out)


@pytest.mark.parametrize(
    "name", ["corridor", "ertis_sample", "panel_wall", "shoebox", "sphere", "wall"]
)
def test_bundled_scenes_edges_are_the_plain_finders(name):
    world = build_world(load_scene(SCENES / f"{name}.toml"))
    edges = world_edges(world)
    ours = sorted(
        (
            tuple(sorted([tuple(np.round(a, 7)), tuple(np.round(b, 7))])),
            round(float(_open(t)), 6),
        )
        for a, b, t in zip(edges.start_m, edges.end_m, edges.angle_rad)
    )
    assert ours == _reference_edges(world)
    if len(edges):
        _check_frames(edges)


def test_edge_codes_sort_stably_either_way():
    rng = np.random.default_rng(5)
    code = rng.integers(0, 1000, 5000)
    expected = np.argsort(code, kind="stable")
    for top in (1000, 2**62):  # one integer with the index, or the radix sort
        order, sorted_code = _sorted_codes(code.copy(), top)  # sorted in place
        np.testing.assert_array_equal(order, expected)
        np.testing.assert_array_equal(sorted_code, code[expected])
