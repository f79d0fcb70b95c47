"""A tessellated edge is one edge: the pieces that a subdivided face cuts an edge
into are joined (acousim.trace.world.edges.merge_collinear), so the diffraction stage's
cost follows the scene's edges, not its tessellation."""

import numpy as np
import trimesh

from acousim.trace.world.edges import find_edges, merge_collinear


def _merged(mesh):
    edges = find_edges(mesh)
    same_key = np.zeros(len(mesh.faces), int)  # one material, planes told by the normals
    return edges, merge_collinear(edges, same_key)


def test_a_subdivided_box_has_its_twelve_edges():
    a, b, c = 0.3, 0.5, 0.7
    box = trimesh.creation.box(extents=(a, b, c))
    fine = box.subdivide().subdivide()  # every edge cut into 4 pieces
    pieces, merged = _merged(fine)
    assert len(pieces) == 48
    assert len(merged) == 12  # a box's edges, each whole again
    assert np.isclose(merged.length_m.sum(), 4 * (a + b + c))
    assert np.allclose(np.sort(merged.length_m), np.repeat([a, b, c], 4))
    assert np.allclose(merged.angle_rad, 1.5 * np.pi)  # every one a convex right angle


def test_an_untessellated_mesh_keeps_its_edges():
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    pieces, merged = _merged(box)
    assert len(pieces) == len(merged) == 12
    assert np.isclose(merged.length_m.sum(), 4 * 6.0)


def test_different_materials_along_one_line_stay_apart():
    """Two coplanar sheets of different materials meeting nowhere but sharing a rim
    line: their rims are joined only within one material."""
    sheet = trimesh.Trimesh(
        vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]],
        faces=[[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]],
    )
    edges = find_edges(sheet)
    one = merge_collinear(edges, np.zeros(4, int))
    two = merge_collinear(edges, np.array([0, 0, 1, 1]))
    y0 = lambda e: np.sum(np.isclose(e.start_m[:, 1], 0) & np.isclose(e.end_m[:, 1], 0))  # noqa: E731
    assert y0(one) == 1 and y0(two) == 2  # the rim along y = 0: one edge, or one per material
