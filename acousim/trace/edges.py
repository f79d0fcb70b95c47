"""Which edges of a mesh diffract: real wedges, not seams.

An edge diffracts when the air around it is a wedge whose open angle ``thW`` is
larger than pi: the rim of a thin sheet (an edge of one face only, ``thW = 2 pi``)
or a convex edge between two faces (a box edge, ``thW = 3 pi / 2``).  Left out:

* coplanar seams of a triangulated face (``thW = pi``: nothing to diffract);
* seams of a tessellated curved surface, where neighbouring faces turn by less than
  :data:`acousim.trace.geometry.CURVED_MAX_ANGLE_DEG` (those belong to the curved-
  surface model of the tracer);
* concave edges (``thW < pi``, inside corners): the image sources of the two faces
  already give their field exactly when ``thW = pi / n`` and nearly otherwise;
* edges shared by more than two faces (non-manifold).

Face normals are taken as outward (towards the air), which holds for closed meshes
with consistent winding; for an open sheet the side does not matter.

Steps of :func:`find_edges`:

1. Merge vertices and list every face-adjacent pair (trimesh) and every edge used by
   one face only.
2. For a pair (A, B): face 1 is A; ``face_dir`` is the unit vector in A's plane,
   perpendicular to the edge, pointing into A; ``normal`` is A's outward normal; the
   open angle is the angle from ``face_dir`` to B's own ``face_dir`` measured through
   the air (towards ``normal``).
3. Keep boundary edges and pairs with ``thW > pi + CURVED_MAX_ANGLE_DEG``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import CURVED_MAX_ANGLE_DEG

__all__ = ["Edges", "find_edges", "triangles_mesh"]


@dataclass(frozen=True, eq=False)
class Edges:
    """E diffracting edges (world frame, metres).

    start_m, end_m (E, 3): endpoints; face_dir (E, 3): unit direction from the edge
    into face 1; normal (E, 3): face 1's outward unit normal; wedge_rad (E,): open
    angle of air around the edge, in (pi, 2 pi]; faces (E, 2): the two faces (face 1
    first; -1 for the missing second face of a sheet's rim).
    """

    start_m: np.ndarray
    end_m: np.ndarray
    face_dir: np.ndarray
    normal: np.ndarray
    wedge_rad: np.ndarray
    faces: np.ndarray

    def __len__(self) -> int:
        return self.wedge_rad.size

    @property
    def length_m(self) -> np.ndarray:
        return np.linalg.norm(self.end_m - self.start_m, axis=1)

    @staticmethod
    def empty() -> Edges:
        z3 = np.zeros((0, 3))
        return Edges(z3, z3, z3, z3, np.zeros(0), np.zeros((0, 2), int))


def triangles_mesh(triangles: np.ndarray):
    """A trimesh mesh from a triangle soup (F, 3, 3), vertices merged, face order kept."""
    import trimesh

    tri = np.asarray(triangles, float)
    mesh = trimesh.Trimesh(
        tri.reshape(-1, 3), np.arange(tri.shape[0] * 3).reshape(-1, 3), process=False
    )
    mesh.merge_vertices()
    return mesh


def _into_face(mesh, faces: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Unit vectors in each face's plane, perpendicular to its edge (vertex pair),
    pointing into the face."""
    v = mesh.vertices
    a, b = v[edges[:, 0]], v[edges[:, 1]]
    axis = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    centre = v[mesh.faces[faces]].mean(axis=1)
    d = centre - a
    d -= np.einsum("ij,ij->i", d, axis)[:, None] * axis
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def find_edges(mesh, min_turn_deg: float = CURVED_MAX_ANGLE_DEG) -> Edges:
    """The diffracting edges of a trimesh mesh (see the module docstring).

    min_turn_deg : a convex edge diffracts when its faces turn by more than this
        (degrees); smaller turns are seams of a curved surface.
    """
    import trimesh

    normals = np.asarray(mesh.face_normals, float)
    v = np.asarray(mesh.vertices, float)
    # 1. adjacent pairs, non-manifold edges left out (trimesh lists each pair once)
    adj = np.asarray(mesh.face_adjacency, int).reshape(-1, 2)
    adj_edges = np.asarray(mesh.face_adjacency_edges, int).reshape(-1, 2)
    sorted_edges = np.sort(np.asarray(mesh.edges, int), axis=1)
    edge_face = np.asarray(mesh.edges_face, int)
    groups = trimesh.grouping.group_rows(sorted_edges)
    single = np.array([g[0] for g in groups if len(g) == 1], int)
    multi = {tuple(sorted_edges[g[0]]) for g in groups if len(g) > 2}
    if multi and adj_edges.size:
        keep = np.array([tuple(e) not in multi for e in np.sort(adj_edges, axis=1)])
        adj, adj_edges = adj[keep], adj_edges[keep]
    # 2. open angle of each pair
    fa, fb = adj[:, 0], adj[:, 1]
    dir_a = _into_face(mesh, fa, adj_edges)
    dir_b = _into_face(mesh, fb, adj_edges)
    na = normals[fa]
    wedge = np.mod(
        np.arctan2(np.einsum("ij,ij->i", dir_b, na), np.einsum("ij,ij->i", dir_b, dir_a)),
        2 * np.pi,
    )
    # 3. real wedges and rims
    real = wedge > np.pi + np.deg2rad(min_turn_deg)
    rim_edges = sorted_edges[single]
    rim_faces = edge_face[single]
    start = np.concatenate([v[adj_edges[real, 0]], v[rim_edges[:, 0]]])
    end = np.concatenate([v[adj_edges[real, 1]], v[rim_edges[:, 1]]])
    face_dir = np.concatenate([dir_a[real], _into_face(mesh, rim_faces, rim_edges)])
    normal = np.concatenate([na[real], normals[rim_faces]])
    wedge_rad = np.concatenate([wedge[real], np.full(rim_faces.size, 2 * np.pi)])
    faces = np.concatenate(
        [adj[real], np.column_stack([rim_faces, np.full(rim_faces.size, -1)])]
    ).astype(int)
    return Edges(start, end, face_dir, normal, wedge_rad, faces)
