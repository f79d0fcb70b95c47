"""The world: every mesh of a scene merged into one triangle set with, per face, its
material, its plane and whether it belongs to a curved surface.

A mesh item with a ``materials`` map ({group: Material}) is read group by group
(:func:`face_groups`), each group's faces taking its material; coplanar faces of
different materials are different planes (a felt panel on a wall is its own
reflector)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acousim.core.materials import MaterialSpectra
from acousim.scene.model import Material, MeshItem, Scene
from processing.errors import InputError

__all__ = ["World", "build_world", "face_groups", "CURVED_MAX_ANGLE_DEG"]

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
    The tracer sees each material's reference numbers (:attr:`Material.reference`);
    `spectra` describes the frequency-dependent ones (None: none) and `interaction`
    (len(materials), 2) the columns of their specular and diffuse interactions in
    the paths' ``interactions`` counts (-1: a material of single numbers).
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
    spectra: MaterialSpectra | None = None
    interaction: np.ndarray | None = None

    @property
    def n_faces(self) -> int:
        return self.triangles.shape[0]

    @property
    def n_interactions(self) -> int:
        """K: columns of the paths' interaction counts (0 without tables)."""
        return 0 if self.spectra is None else self.spectra.n_columns

    def face_values(self, attr: str) -> np.ndarray:
        """(F,) a material attribute per face; reflection and diffuse are the
        tracer's reference numbers (:attr:`Material.reference`)."""
        ref = {"reflection": 0, "diffuse": 1}
        if attr in ref:
            values = [m.reference[ref[attr]] for m in self.materials]
        else:
            values = [getattr(m, attr) for m in self.materials]
        return np.array(values)[self.material]

    def face_interactions(self, mode: int) -> np.ndarray:
        """(F,) the interaction column of each face's material for `mode` (0:
        specular, 1: diffuse), -1 for materials of single numbers; None without
        tables."""
        if self.spectra is None:
            return None
        return self.interaction[self.material, mode]

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
    from acousim.scene.pose import MAX_COORDINATE_M

    # checked before transforming: a product of huge numbers would overflow first
    T = np.asarray(transform, float)
    reach = float(np.abs(mesh.vertices).max()) * float(np.abs(T[:3, :3]).sum(axis=1).max())
    if not reach + float(np.abs(T[:3, 3]).max()) <= MAX_COORDINATE_M:
        raise InputError(
            f"mesh vertices reach beyond +-{MAX_COORDINATE_M:g} m once placed",
            file=_name(path),
        )
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


def face_groups(path, transform) -> tuple[object, dict[str, np.ndarray]]:
    """A mesh file read group by group: the merged mesh (as :func:`_load` gives it)
    and, for every name a group answers to, its faces (bool (F,)).

    A file that trimesh reads as a scene has one geometry per group: OBJ groups
    (``g``) and objects (``o``), or ``usemtl`` materials when the .mtl file is
    present; GLB/GLTF meshes placed by nodes.  A group answers to its node name,
    its geometry name and its visual material's name.  A mesh in memory
    (``trimesh.Trimesh``) or a file of one group has the single group ``""``.
    """
    import trimesh

    if isinstance(path, trimesh.Trimesh):
        mesh = _load(path, transform)
        return mesh, {"": np.ones(len(mesh.faces), bool)}
    try:
        loaded = trimesh.load(path, process=False, split_groups=True)
    except TypeError:  # a loader without OBJ's split_groups
        loaded = trimesh.load(path, process=False)
    except Exception as exc:  # trimesh raises many kinds
        raise InputError(f"cannot read mesh ({exc})", file=_name(path)) from None
    if not isinstance(loaded, trimesh.Scene):
        mesh = _load(loaded, transform)
        return mesh, {"": np.ones(len(mesh.faces), bool)}
    parts, names = [], []
    for node in loaded.graph.nodes_geometry:
        T, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not hasattr(geom, "faces") or len(geom.faces) == 0:
            continue
        part = _load(geom, np.asarray(transform) @ T)
        material = getattr(getattr(geom.visual, "material", None), "name", None)
        parts.append(part)
        names.append({str(n) for n in (node, geom_name, material) if n})
    if not parts:
        raise InputError("mesh has no faces", file=_name(path))
    mesh = trimesh.util.concatenate(parts)
    mesh.merge_vertices()  # the groups of one file stay connected (face order kept)
    sizes = np.cumsum([0] + [len(p.faces) for p in parts])
    groups: dict[str, np.ndarray] = {}
    for i, answers in enumerate(names):
        for n in answers:
            groups.setdefault(n, np.zeros(len(mesh.faces), bool))[sizes[i] : sizes[i + 1]] = True
    return mesh, groups


def _material_of_faces(item: MeshItem, index: int, scene: Scene, names: list[str]):
    """The mesh of `item` and its faces' material indices into `names`."""
    if not item.materials:
        mesh = _load(item.mesh, item.transform)
        return mesh, np.full(len(mesh.faces), names.index(item.material.name))
    mesh, groups = face_groups(item.mesh, item.transform)
    mat = np.full(len(mesh.faces), names.index(item.material.name))
    for group, material in item.materials.items():
        if group not in groups:
            raise InputError(
                f"mesh {_name(item.mesh)} has no group {group!r} (its groups: "
                f"{', '.join(sorted(g for g in groups if g)) or 'none'})",
                file=scene.source,
                key=f"meshes[{index}].materials",
                value=group,
            )
        mat[groups[group]] = names.index(material.name)
    return mesh, mat


def build_world(scene: Scene) -> World:
    """Load, transform, clean and merge the meshes of a scene."""
    import trimesh

    meshes, mat_index = [], []
    materials = list(
        {
            m.name: m for item in scene.meshes for m in (item.material, *item.materials.values())
        }.values()
    )
    names = [m.name for m in materials]
    for i, item in enumerate(scene.meshes):
        mesh, mat = _material_of_faces(item, i, scene, names)
        meshes.append(mesh)
        mat_index.append(mat)
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
    material = np.concatenate(mat_index)
    # coplanar faces share a plane id: normals rounded to 1e-6, offsets to 10 µm;
    # faces of another material are another plane
    key = np.column_stack([np.round(normals, 6), np.round(offsets, 5)])
    if len(materials) > 1:
        key = np.column_stack([key, material])
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
        material,
        tuple(materials),
        np.asarray(merged.area_faces),
        np.asarray(component),
        *_spectra(materials),
    )


def _spectra(materials: list[Material]) -> tuple[MaterialSpectra | None, np.ndarray | None]:
    """The frequency-dependent materials' spectra and the interaction columns of
    every material (see :class:`World`)."""
    tables = [m for m in materials if m.frequency_dependent]
    if not tables:
        return None, None
    column = np.full((len(materials), 2), -1)
    for j, m in enumerate(tables):
        column[materials.index(m)] = (2 * j, 2 * j + 1)

    def arr(m, attr):
        return np.broadcast_to(np.asarray(getattr(m, attr), float), (len(m.frequencies_khz),))

    spectra = MaterialSpectra(
        tuple(m.name for m in tables),
        tuple(np.multiply(m.frequencies_khz, 1e3) for m in tables),
        tuple(arr(m, "reflection") for m in tables),
        tuple(arr(m, "diffuse") for m in tables),
        np.array([m.reference for m in tables], float),
    )
    return spectra, column
