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

Which side of an edge is air is not read from the face normals (a room's walls and
a box's faces are wound differently, and sheets have no inside): an edge keeps both
of its sides, and :meth:`Edges.oriented` picks, for a source and a receiver, the side
they are in.  That side diffracts if it is a convex wedge (open angle above pi plus
the curved-surface threshold); an inside corner (open angle below pi) does not.

Steps of :func:`find_edges`:

1. Merge vertices and list every face-adjacent pair (trimesh) and every edge used by
   one face only.
2. For a pair (A, B): ``face_dir`` is the unit vector in A's plane, perpendicular to
   the edge, pointing into A; ``normal`` is A's unit normal; ``angle_rad`` is the
   angle from ``face_dir`` to B's own direction ``other_dir``, turning towards
   ``normal``: the open angle of that side (the other side's is 2 pi minus it).
3. Keep rims and pairs whose faces turn by more than ``min_turn_deg`` either way
   (not coplanar seams, not seams of curved surfaces).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .geometry import CURVED_MAX_ANGLE_DEG

__all__ = ["Edges", "find_edges", "merge_collinear", "triangles_mesh"]


@dataclass(frozen=True, eq=False)
class Edges:
    """E candidate diffracting edges (world frame, metres)."""

    start_m: np.ndarray
    """(E, 3) first endpoints, m."""
    end_m: np.ndarray
    """(E, 3) second endpoints, m."""
    face_dir: np.ndarray
    """(E, 3) unit direction from the edge into face 1."""
    normal: np.ndarray
    """(E, 3) face 1's unit normal (either side)."""
    other_dir: np.ndarray
    """(E, 3) unit direction from the edge into face 2 (face 1's for a rim)."""
    angle_rad: np.ndarray
    """(E,) angle from face_dir to other_dir turning towards normal (2 pi for a rim),
    rad."""
    faces: np.ndarray
    """(E, 2) int, face 1 and face 2 (-1 for the missing second face of a rim)."""

    def __len__(self) -> int:
        return self.angle_rad.size

    @property
    def length_m(self) -> np.ndarray:
        return np.linalg.norm(self.end_m - self.start_m, axis=1)

    def select(self, keep: np.ndarray) -> Edges:
        return Edges(*(getattr(self, f.name)[keep] for f in fields(self)))

    def oriented(
        self, source: np.ndarray, receiver: np.ndarray, min_turn_deg: float = CURVED_MAX_ANGLE_DEG
    ) -> tuple[np.ndarray, Edges]:
        """The edges as wedges seen from the side of `source` and `receiver` (3,).

        Returns (keep (E,), edges) where ``keep`` marks the edges whose source side
        is also the receiver's and is a convex wedge (open angle above pi +
        min_turn_deg), and ``edges`` has, per edge, face 1 and its normal chosen so
        that the air is at angles 0 .. angle_rad (the open angle of that side).
        """
        axis = self.end_m - self.start_m
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)

        def theta(p):
            v = p - self.start_m
            v -= np.einsum("ij,ij->i", v, axis)[:, None] * axis
            a = np.arctan2(
                np.einsum("ij,ij->i", v, self.normal), np.einsum("ij,ij->i", v, self.face_dir)
            )
            return np.mod(a, 2 * np.pi)

        ts, tr = theta(np.asarray(source, float)), theta(np.asarray(receiver, float))
        side_s, side_r = ts > self.angle_rad, tr > self.angle_rad  # True: the other side
        flip = side_s[:, None]
        turn = np.cross(self.face_dir, self.normal)  # rotation axis of the angles
        normal_b = np.cross(turn, self.other_dir)
        oriented = Edges(
            self.start_m,
            self.end_m,
            np.where(flip, self.other_dir, self.face_dir),
            np.where(flip, normal_b, self.normal),
            np.where(flip, self.face_dir, self.other_dir),
            np.where(side_s, 2 * np.pi - self.angle_rad, self.angle_rad),
            np.where(flip & (self.faces[:, 1:] >= 0), self.faces[:, ::-1], self.faces),
        )
        keep = (side_s == side_r) & (oriented.angle_rad > np.pi + np.deg2rad(min_turn_deg))
        return keep, oriented

    @staticmethod
    def empty() -> Edges:
        z3 = np.zeros((0, 3))
        return Edges(z3, z3, z3, z3, z3, np.zeros(0), np.zeros((0, 2), int))


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

    min_turn_deg : an edge is kept when its faces turn by more than this (degrees)
        either way; smaller turns are seams of a curved surface.
    """

    normals = np.asarray(mesh.face_normals, float)
    v = np.asarray(mesh.vertices, float)
    # 1. adjacent pairs, non-manifold edges left out (trimesh lists each pair once)
    adj = np.asarray(mesh.face_adjacency, int).reshape(-1, 2)
    adj_edges = np.asarray(mesh.face_adjacency_edges, int).reshape(-1, 2)
    sorted_edges = np.sort(np.asarray(mesh.edges, int), axis=1)
    edge_face = np.asarray(mesh.edges_face, int)
    # each vertex pair as one integer: the edges used by one face (rims) and by more
    # than two (non-manifold), without a Python loop over the edges
    n_v = np.int64(max(len(v), 1))
    code = sorted_edges[:, 0].astype(np.int64) * n_v + sorted_edges[:, 1]
    _, first, count = np.unique(code, return_index=True, return_counts=True)
    single = np.sort(first[count == 1])
    multi = np.unique(code)[count > 2]
    if multi.size and adj_edges.size:
        pair = np.sort(adj_edges, axis=1)
        keep = ~np.isin(pair[:, 0].astype(np.int64) * n_v + pair[:, 1], multi)
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
    # 3. real wedges (either side) and rims
    real = np.abs(wedge - np.pi) > np.deg2rad(min_turn_deg)
    rim_edges = sorted_edges[single]
    rim_faces = edge_face[single]
    start = np.concatenate([v[adj_edges[real, 0]], v[rim_edges[:, 0]]])
    end = np.concatenate([v[adj_edges[real, 1]], v[rim_edges[:, 1]]])
    rim_dir = _into_face(mesh, rim_faces, rim_edges)
    face_dir = np.concatenate([dir_a[real], rim_dir])
    normal = np.concatenate([na[real], normals[rim_faces]])
    other_dir = np.concatenate([dir_b[real], rim_dir])
    angle = np.concatenate([wedge[real], np.full(rim_faces.size, 2 * np.pi)])
    faces = np.concatenate(
        [adj[real], np.column_stack([rim_faces, np.full(rim_faces.size, -1)])]
    ).astype(int)
    return Edges(start, end, face_dir, normal, other_dir, angle, faces)


def merge_collinear(edges: Edges, face_key: np.ndarray, tol_m: float = 1e-6) -> Edges:
    """`edges` with the collinear pieces of one straight edge joined: a tessellated
    face cuts an edge into segments end to end, which are one wedge (same line,
    same faces' planes and materials by `face_key` (F,), same face directions and open
    angle). Joining them makes the stage's cost depend on the scene's edges, not on
    its tessellation (the elements of one long edge are those of its pieces)."""
    if len(edges) < 2:
        return edges
    d = edges.end_m - edges.start_m
    length = np.linalg.norm(d, axis=1)
    u = d / np.where(length > 0, length, 1.0)[:, None]
    # 1. a canonical direction for each line, so that both windings of it agree
    lead = np.take_along_axis(u, np.argmax(np.abs(u), axis=1)[:, None], axis=1)[:, 0]
    flip = lead < 0
    u = np.where(flip[:, None], -u, u)
    start = np.where(flip[:, None], edges.end_m, edges.start_m)
    end = np.where(flip[:, None], edges.start_m, edges.end_m)
    t0, t1 = np.einsum("ij,ij->i", start, u), np.einsum("ij,ij->i", end, u)
    foot = start - t0[:, None] * u  # the line's point nearest the origin
    # 2. the wedges that may be one: same line, faces' keys, directions and angle
    f = edges.faces
    keys = np.column_stack(
        [
            np.round(u * 1e6),
            np.round(foot / tol_m),
            np.round(edges.face_dir * 1e6),
            np.round(edges.normal * 1e6),
            np.round(edges.other_dir * 1e6),
            np.round(edges.angle_rad * 1e6),
            face_key[f[:, 0]],
            np.where(f[:, 1] >= 0, face_key[np.maximum(f[:, 1], 0)], -1),
        ]
    )
    group = np.unique(keys, axis=0, return_inverse=True)[1].ravel()
    # 3. along each line, pieces that touch (within tol_m) are joined
    order = np.lexsort((t0, group))
    g, a, b = group[order], t0[order], t1[order]
    new = np.ones(order.size, bool)
    run_end = b[0]
    for k in range(1, order.size):  # a short loop over the edges (thousands)
        if g[k] == g[k - 1] and a[k] <= run_end + tol_m:
            new[k] = False
            run_end = max(run_end, b[k])
        else:
            run_end = b[k]
    run = np.cumsum(new) - 1
    first = order[new]
    lo = np.full(first.size, np.inf)
    hi = np.full(first.size, -np.inf)
    np.minimum.at(lo, run, a)
    np.maximum.at(hi, run, b)
    out = edges.select(first)
    uu, pf = u[first], foot[first]
    return Edges(
        pf + lo[:, None] * uu,
        pf + hi[:, None] * uu,
        out.face_dir,
        out.normal,
        out.other_dir,
        out.angle_rad,
        out.faces,
    )
