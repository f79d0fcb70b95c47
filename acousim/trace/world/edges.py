"""Which edges of a mesh diffract: real wedges, not seams.

An edge diffracts when the air around it is a wedge whose open angle ``thW`` is
larger than pi: the rim of a thin sheet (an edge of one face only, ``thW = 2 pi``)
or a convex edge between two faces (a box edge, ``thW = 3 pi / 2``).  Left out:

* coplanar seams of a triangulated face (``thW = pi``: nothing to diffract);
* seams of a tessellated curved surface, where neighbouring faces turn by less than
  :data:`acousim.trace.world.build.CURVED_MAX_ANGLE_DEG` (those belong to the curved-
  surface model of the tracer);
* concave edges (``thW < pi``, inside corners): the image sources of the two faces
  already give their field exactly when ``thW = pi / n`` and nearly otherwise;
* edges shared by more than two faces (non-manifold).

Which side of an edge is air is not read from the face normals (a room's walls and
a box's faces are wound differently, and sheets have no inside): an edge keeps both
of its sides, and :meth:`Edges.oriented` picks, for a source and a receiver, the side
they are in.  That side diffracts if it is a convex wedge (open angle above pi plus
the curved-surface threshold); an inside corner (open angle below pi) does not.

Steps of :func:`find_edges` (a trimesh mesh) and :func:`world_edges` (a world):

1. List every pair of faces sharing an edge and every edge used by one face only
   (:func:`acousim.trace.world.mesh_index.edge_table`, one sort of integer edge codes).
   A pair of faces on one plane that lie on either side of their edge is a flat
   seam and is not measured (most pairs of a finely tessellated wall).
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

from acousim.trace.world.build import CURVED_MAX_ANGLE_DEG, World, plane_ids
from acousim.trace.world.mesh_index import EdgeTable, edge_table, merged_vertex_ids

__all__ = ["EdgeFrame", "Edges", "convex", "find_edges", "merge_collinear", "world_edges"]


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
        self,
        source: np.ndarray,
        receiver: np.ndarray,
        min_turn_deg: float = CURVED_MAX_ANGLE_DEG,
    ) -> tuple[np.ndarray, Edges]:
        """The edges as wedges seen from the side of `source` and `receiver` (3,).

        Returns (keep (E,), edges) where ``keep`` marks the edges whose source side
        is also the receiver's and is a convex wedge (open angle above pi +
        min_turn_deg), and ``edges`` has, per edge, face 1 and its normal chosen so
        that the air is at angles 0 .. angle_rad (the open angle of that side).
        """
        frame = EdgeFrame.of(self)
        side_s = frame.theta(self, source) > self.angle_rad  # True: the other side
        side_r = frame.theta(self, receiver) > self.angle_rad
        oriented = frame.turned(self, side_s)
        return (side_s == side_r) & convex(oriented, min_turn_deg), oriented

    @staticmethod
    def empty() -> Edges:
        z3 = np.zeros((0, 3))
        return Edges(z3, z3, z3, z3, z3, np.zeros(0), np.zeros((0, 2), int))


def convex(edges: Edges, min_turn_deg: float = CURVED_MAX_ANGLE_DEG) -> np.ndarray:
    """(E,) True where the open angle of `edges` (oriented) is above pi + min_turn_deg."""
    return edges.angle_rad > np.pi + np.deg2rad(min_turn_deg)


@dataclass(frozen=True, eq=False)
class EdgeFrame:
    """What the diffraction stage asks of E edges that depends on neither the
    source nor the receiver (found once per set of edges: :meth:`Edges.oriented`,
    the distances to the edges, the edge pairs' axes)."""

    span: np.ndarray
    """(E, 3) end minus start (m)."""
    span2: np.ndarray
    """(E,) its squared length (m^2)."""
    length: np.ndarray
    """(E,) its length (m)."""
    axis: np.ndarray
    """(E, 3) unit vector from start to end."""
    normal_b: np.ndarray
    """(E, 3) face 2's normal on the side of face 1's (turning the same way)."""

    @classmethod
    def of(cls, edges: Edges) -> EdgeFrame:
        span = edges.end_m - edges.start_m
        length = np.linalg.norm(span, axis=1)
        axis = span / np.where(length > 0, length, 1.0)[:, None]
        turn = np.cross(edges.face_dir, edges.normal)  # rotation axis of the angles
        span2 = np.einsum("ij,ij->i", span, span)
        return cls(span, span2, length, axis, np.cross(turn, edges.other_dir))

    def theta(self, edges: Edges, p: np.ndarray) -> np.ndarray:
        """(E,) the angle of point p (3,) about each edge, from face 1 towards its
        normal, in [0, 2 pi)."""
        v = np.asarray(p, float) - edges.start_m
        v -= np.einsum("ij,ij->i", v, self.axis)[:, None] * self.axis
        a = np.arctan2(
            np.einsum("ij,ij->i", v, edges.normal), np.einsum("ij,ij->i", v, edges.face_dir)
        )
        return np.mod(a, 2 * np.pi)

    def turned(self, edges: Edges, flip: np.ndarray) -> Edges:
        """`edges` with faces 1 and 2 swapped where `flip` (E,) (seen from the other
        side: the open angle is 2 pi minus the angle)."""
        f = flip[:, None]
        return Edges(
            edges.start_m,
            edges.end_m,
            np.where(f, edges.other_dir, edges.face_dir),
            np.where(f, self.normal_b, edges.normal),
            np.where(f, edges.face_dir, edges.other_dir),
            np.where(flip, 2 * np.pi - edges.angle_rad, edges.angle_rad),
            np.where(f & (edges.faces[:, 1:] >= 0), edges.faces[:, ::-1], edges.faces),
        )


def _into_face(
    vertices: np.ndarray, faces: np.ndarray, face: np.ndarray, edge: np.ndarray
) -> np.ndarray:
    """Unit vectors (n, 3) in the plane of each face `face` (n,), perpendicular to its
    edge `edge` (n, 2) (vertex ids), pointing into the face.  vertices (V, 3) m,
    faces (F, 3) vertex ids."""
    a, b = vertices[edge[:, 0]], vertices[edge[:, 1]]
    axis = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    centre = vertices[faces[face]].mean(axis=1)
    d = centre - a
    d -= np.einsum("ij,ij->i", d, axis)[:, None] * axis
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _wedges(
    vertices: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray,
    table: EdgeTable,
    flat: np.ndarray,
    min_turn_deg: float,
    rank: np.ndarray | None = None,
) -> Edges:
    """Steps 2 and 3 of :func:`find_edges`: the open angle of every pair of `table`
    not marked `flat` (A,) (a seam between two faces of one plane, known to turn by
    nothing), the real wedges among them, and the rims.  vertices (V, 3) m, faces
    (F, 3) vertex ids, normals (F, 3) unit; rank (V,): the order in which an edge's
    ends are listed (None: by vertex id)."""
    adj, adj_edges = table.pairs[~flat], _ordered(table.shared[~flat], rank)
    fa, fb = adj[:, 0], adj[:, 1]
    dir_a = _into_face(vertices, faces, fa, adj_edges)
    dir_b = _into_face(vertices, faces, fb, adj_edges)
    na = normals[fa]
    wedge = np.mod(
        np.arctan2(np.einsum("ij,ij->i", dir_b, na), np.einsum("ij,ij->i", dir_b, dir_a)),
        2 * np.pi,
    )
    real = np.abs(wedge - np.pi) > np.deg2rad(min_turn_deg)
    rim_faces, rim_edges = table.rim_face, _ordered(table.rim_edge, rank)
    rim_dir = _into_face(vertices, faces, rim_faces, rim_edges)
    return Edges(
        np.concatenate([vertices[adj_edges[real, 0]], vertices[rim_edges[:, 0]]]),
        np.concatenate([vertices[adj_edges[real, 1]], vertices[rim_edges[:, 1]]]),
        np.concatenate([dir_a[real], rim_dir]),
        np.concatenate([na[real], normals[rim_faces]]),
        np.concatenate([dir_b[real], rim_dir]),
        np.concatenate([wedge[real], np.full(rim_faces.size, 2 * np.pi)]),
        np.concatenate(
            [adj[real], np.column_stack([rim_faces, np.full(rim_faces.size, -1)])]
        ).astype(int),
    )


def _ordered(edges: np.ndarray, rank: np.ndarray | None) -> np.ndarray:
    """Edges (n, 2) (vertex ids) with their ends in ascending `rank` (V,)."""
    if rank is None:
        return edges
    swap = rank[edges[:, 0]] > rank[edges[:, 1]]
    return np.where(swap[:, None], edges[:, ::-1], edges)


def find_edges(mesh, min_turn_deg: float = CURVED_MAX_ANGLE_DEG) -> Edges:
    """The diffracting edges of a trimesh mesh (see the module docstring), over its
    own vertices (merge them first for a triangle soup).

    min_turn_deg : an edge is kept when its faces turn by more than this (degrees)
        either way; smaller turns are seams of a curved surface.
    """
    vertices = np.asarray(mesh.vertices, float)
    faces = np.asarray(mesh.faces, int)
    normals = np.asarray(mesh.face_normals, float)
    plane = plane_ids(normals, np.einsum("fi,fi->f", normals, vertices[faces[:, 0]]))
    table = edge_table(faces)
    return _wedges(vertices, faces, normals, table, _flat(table, plane), min_turn_deg)


def world_edges(world: World, min_turn_deg: float = CURVED_MAX_ANGLE_DEG) -> Edges:
    """The diffracting edges of a world: those of its triangles with their vertices
    merged across meshes (as trimesh's ``merge_vertices`` merges them), found from the
    world's own indexed faces, planes and edge table (:attr:`World.edge_table`,
    sorted again only when meshes share vertices: :attr:`World.vertex_groups`).
    Only the pairs of faces on different planes (or folded onto one) are measured:
    a tessellated wall's seams cost nothing.  min_turn_deg as in :func:`find_edges`."""
    if world.vertices is None:  # a triangle soup
        vertices = world.triangles.reshape(-1, 3)
        faces = np.arange(3 * world.n_faces).reshape(-1, 3)
        first, inverse = merged_vertex_ids(vertices)
    else:
        vertices, faces = world.vertices, world.faces
        first, inverse = world.vertex_groups
    if world.vertices is not None and len(first) == len(vertices):
        table = world.edge_table
    else:
        vertices, faces = vertices[first], inverse[faces]
        table = edge_table(faces)
    # an edge's ends listed in the order the faces first use them, as in a triangle
    # soup merged by trimesh (the same numbers to the last bit)
    corners = faces.ravel()
    rank = np.empty(len(vertices), np.int64)
    rank[corners[::-1]] = np.arange(len(corners))[::-1]  # the last write is the first use
    flat = _flat(table, world.plane)
    return _wedges(vertices, faces, world.normals, table, flat, min_turn_deg, rank)


def _flat(table: EdgeTable, plane: np.ndarray) -> np.ndarray:
    """(A,) bool: pairs of `table` that are flat seams: both faces on one plane (ids
    `plane` (F,): normals equal within 1e-6) on either side of the edge (they run
    along it in opposite directions).  Their open angle is pi: never a wedge."""
    return (plane[table.pairs[:, 0]] == plane[table.pairs[:, 1]]) & ~table.same_way


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
