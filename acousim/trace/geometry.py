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
    vn = np.asarray(merged.vertex_normals, float)[merged.faces]
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
