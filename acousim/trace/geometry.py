"""The world: every mesh of a scene merged into one triangle set with, per face, its
material, its plane and whether it belongs to a curved surface."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acousim.scene.model import Material, Scene
from processing.errors import InputError

__all__ = ["World", "build_world", "CURVED_MAX_ANGLE_DEG"]

#: adjacent faces meeting at a dihedral angle between 0.05 and this many degrees are a
#: tessellated curved surface (sphere, pipe); sharper edges are corners of planar walls
CURVED_MAX_ANGLE_DEG = 30.0
_FLAT_ANGLE = np.deg2rad(0.05)


@dataclass(frozen=True, eq=False)
class World:
    """Merged scene geometry (world frame, metres).

    triangles : (F, 3, 3); normals : (F, 3) unit; offsets : (F,) with n . x = offset
    on the face's plane; plane : (F,) plane id shared by coplanar faces; curved : (F,)
    bool; vertex_normals : (F, 3, 3) smooth normals at the corners (for curved faces);
    material : (F,) index into `materials`; component : (F,) connected surface id.
    """

    triangles: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    plane: np.ndarray
    curved: np.ndarray
    vertex_normals: np.ndarray
    material: np.ndarray
    materials: tuple[Material, ...]
    area: np.ndarray
    component: np.ndarray

    @property
    def n_faces(self) -> int:
        return self.triangles.shape[0]

    def face_values(self, attr: str) -> np.ndarray:
        return np.array([getattr(m, attr) for m in self.materials])[self.material]

    @property
    def n_planes(self) -> int:
        return int(self.plane.max()) + 1

    @property
    def surface(self) -> np.ndarray:
        """(F,) surface id: the plane for planar faces, n_planes + the connected
        component for curved faces (one id per curved object)."""
        return np.where(self.curved, self.n_planes + self.component, self.plane)

    def normals_at(self, x: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Unit normals (K, 3) at points x (K, 3) on faces f (K,): the face normal,
        smooth (barycentric interpolation of the vertex normals) on curved faces."""
        n = self.normals[f].copy()
        cv = self.curved[f]
        if cv.any():
            from trimesh.triangles import points_to_barycentric

            b = points_to_barycentric(self.triangles[f[cv]], x[cv])
            sm = np.einsum("ki,kij->kj", b, self.vertex_normals[f[cv]])
            n[cv] = sm / np.linalg.norm(sm, axis=1, keepdims=True)
        return n


def _name(mesh) -> str:
    """How a mesh is named in an error: its file, or what it is (a mesh in memory)."""
    return str(mesh) if isinstance(mesh, str | Path) else f"<{type(mesh).__name__} in memory>"


def _load(path, transform) -> object:
    import trimesh

    try:  # a trimesh.Trimesh in memory is copied, never changed
        mesh = (
            path.copy()
            if isinstance(path, trimesh.Trimesh)
            else trimesh.load(path, force="mesh", process=False)
        )
    except Exception as exc:  # trimesh raises many kinds
        raise InputError(f"cannot read mesh ({exc})", file=_name(path)) from None
    if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
        raise InputError("mesh has no faces", file=_name(path))
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("mesh has NaN or inf vertices", file=_name(path))
    mesh.apply_transform(transform)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces(height=1e-9))
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise InputError("every face of the mesh is degenerate", file=_name(path))
    return mesh


def smooth_corner_normals(
    triangles: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray,
    adjacency: np.ndarray,
    angles: np.ndarray,
    edges: np.ndarray,
) -> np.ndarray:
    """Smooth normals (F, 3, 3) at the corners of every face, averaged only across the
    edges of a curved surface.

    1. Every corner (face, vertex) is a node; two faces that share an edge at a
       dihedral angle below ``CURVED_MAX_ANGLE_DEG`` join their corners at both ends
       of that edge.  Sharper edges (a cylinder's rim, a box's corner) join nothing,
       so each side of them keeps its own normal.
    2. The corners joined around a vertex form one smoothing group; its normal is the
       sum of its faces' normals weighted by their angle at the vertex.

    triangles (F, 3, 3), faces (F, 3) vertex indices, normals (F, 3), adjacency (A, 2)
    face pairs with their dihedral angles (A,) in radians and shared edges (A, 2).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from trimesh.triangles import angles as corner_angles

    n_faces = len(faces)
    smooth = angles < np.deg2rad(CURVED_MAX_ANGLE_DEG)
    pairs, shared = adjacency[smooth], edges[smooth]
    rows, cols = [], []
    for end in range(2):
        v = shared[:, end]
        # the corner of each face of the pair at vertex v
        c0 = pairs[:, 0] * 3 + np.argmax(faces[pairs[:, 0]] == v[:, None], axis=1)
        c1 = pairs[:, 1] * 3 + np.argmax(faces[pairs[:, 1]] == v[:, None], axis=1)
        rows.append(c0)
        cols.append(c1)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(rows.size), (rows, cols)), shape=(3 * n_faces,) * 2)
    _, group = connected_components(graph, directed=False)
    weight = corner_angles(triangles).ravel()
    contrib = np.repeat(normals, 3, axis=0) * weight[:, None]
    total = np.zeros((group.max() + 1, 3))
    np.add.at(total, group, contrib)
    out = total[group]
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    out = np.where(norm > 0, out / np.where(norm > 0, norm, 1), np.repeat(normals, 3, axis=0))
    return out.reshape(n_faces, 3, 3)


def build_world(scene: Scene) -> World:
    """Load, transform, clean and merge the meshes of a scene."""
    import trimesh

    meshes, mat_index = [], []
    materials = list({m.material.name: m.material for m in scene.meshes}.values())
    names = [m.name for m in materials]
    for item in scene.meshes:
        mesh = _load(item.mesh, item.transform)
        meshes.append(mesh)
        mat_index.append(np.full(len(mesh.faces), names.index(item.material.name)))
    merged = trimesh.util.concatenate(meshes)
    tri = np.asarray(merged.triangles, float)
    normals = np.asarray(merged.face_normals, float)
    offsets = np.einsum("fi,fi->f", normals, tri[:, 0])
    # curved faces: a neighbour at a small but non-zero dihedral angle
    curved = np.zeros(len(tri), bool)
    adj = merged.face_adjacency
    ang = merged.face_adjacency_angles
    smooth = (ang > _FLAT_ANGLE) & (ang < np.deg2rad(CURVED_MAX_ANGLE_DEG))
    curved[adj[smooth].ravel()] = True
    # coplanar faces share a plane id: normals rounded to 1e-6, offsets to 10 µm
    key = np.column_stack([np.round(normals, 6), np.round(offsets, 5)])
    _, plane = np.unique(key, axis=0, return_inverse=True)
    vn = smooth_corner_normals(
        tri, np.asarray(merged.faces), normals, adj, ang, merged.face_adjacency_edges
    )
    vn = np.where(curved[:, None, None], vn, normals[:, None, :])
    component = trimesh.graph.connected_component_labels(adj, node_count=len(tri))
    return World(
        tri,
        normals,
        offsets,
        plane.ravel(),
        curved,
        vn,
        np.concatenate(mat_index),
        tuple(materials),
        np.asarray(merged.area_faces),
        np.asarray(component),
    )
