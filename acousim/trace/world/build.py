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
from acousim.scene.mesh_file import read_mesh
from acousim.scene.model import Material, MeshItem, Scene
from acousim.scene.pose import MAX_COORDINATE_M
from acousim.trace.world.mesh_index import (
    EdgeTable,
    MeshPart,
    clean_mesh,
    edge_table,
    face_adjacency,
    face_cross,
    face_frames,
    merged_vertex_ids,
    radix_argsort,
    row_groups,
)
from processing.base.errors import InputError

__all__ = [
    "World",
    "build_world",
    "face_groups",
    "plane_ids",
    "face_adjacency",
    "radix_argsort",
    "row_groups",
    "CURVED_MAX_ANGLE_DEG",
]

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
    vertices (V, 3) and faces (F, 3) (vertex indices): the same triangles, indexed,
    every vertex a corner of a face (for the ray caster; None: use `triangles`).
    owner : (F,) int, the index of the scene's mesh each face belongs to (None:
    not known); with `material`, what a path touched (the ground truth's objects).
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
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    owner: np.ndarray | None = None

    @property
    def n_faces(self) -> int:
        return self.triangles.shape[0]

    @property
    def n_interactions(self) -> int:
        """K: columns of the paths' interaction counts (0 without tables)."""
        return 0 if self.spectra is None else self.spectra.n_columns

    def _cached(self, key, make):
        """A derived array computed once per world (read-only): per-pose work then
        depends on planes and paths, not on the number of faces."""
        cache = self.__dict__.setdefault("_derived", {})
        if key not in cache:
            value = make()
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
            cache[key] = value
        return cache[key]

    def face_values(self, attr: str) -> np.ndarray:
        """(F,) a material attribute per face; reflection and diffuse are the
        tracer's reference numbers (:attr:`Material.reference`).  Read-only."""

        def make():
            ref = {"reflection": 0, "diffuse": 1}
            if attr in ref:
                values = [m.reference[ref[attr]] for m in self.materials]
            else:
                values = [getattr(m, attr) for m in self.materials]
            return np.array(values)[self.material]

        return self._cached(("values", attr), make)

    @property
    def plane_first(self) -> np.ndarray:
        """(n_planes,) the first face of every plane (read-only)."""

        def make():
            first = np.full(self.n_planes, -1)
            first[self.plane[::-1]] = np.arange(self.n_faces)[::-1]
            return first

        return self._cached("plane_first", make)

    def plane_faces(self, pid: int) -> tuple[np.ndarray, np.ndarray]:
        """The faces of plane `pid` (ascending) and their bounding boxes (n, 2, 3)."""

        order, starts, (lo, hi) = self._plane_index()
        faces = order[starts[pid] : starts[pid + 1]]
        return faces, np.stack([lo[faces], hi[faces]], axis=1)

    def faces_near(self, pid: int, x: np.ndarray, grow: float) -> tuple[np.ndarray, np.ndarray]:
        """(row, face) pairs: the faces of plane `pid` whose bounding box, grown by
        `grow` (m), holds the point x[row] (x: (n, 3)).  The plane's faces are kept
        sorted along the axis of its largest extent, so only a strip one face wide
        around each point is tested (not every face of a finely tessellated wall)."""
        strips = self._cached("plane_strips", dict)
        if pid not in strips:
            faces, box = self.plane_faces(pid)
            axis = int(np.argmax(box[:, 1].max(axis=0) - box[:, 0].min(axis=0)))
            o = np.argsort(box[:, 0, axis], kind="stable")
            width = float((box[:, 1, axis] - box[:, 0, axis]).max())
            strips[pid] = (axis, faces[o], box[o], box[o, 0, axis], width)
        axis, faces, box, lo, width = strips[pid]
        i0 = np.searchsorted(lo, x[:, axis] - grow - width, "left")
        count = np.searchsorted(lo, x[:, axis] + grow, "right") - i0
        row = np.repeat(np.arange(len(x)), count)
        k = np.repeat(i0 - np.cumsum(count) + count, count) + np.arange(count.sum())
        p = x[row]
        near = np.all((box[k, 0] - grow <= p) & (p <= box[k, 1] + grow), axis=1)
        return row[near], faces[k[near]]

    @property
    def plane_boxes(self) -> np.ndarray:
        """(n_planes, 2, 3) the bounding box of every plane's faces (read-only)."""

        def make():
            order, starts, (lo, hi) = self._plane_index()
            lo = np.minimum.reduceat(lo[order], starts[:-1], axis=0)
            hi = np.maximum.reduceat(hi[order], starts[:-1], axis=0)
            return np.stack([lo, hi], axis=1)

        return self._cached("plane_boxes", make)

    def _plane_index(self):
        """Faces sorted by plane, where each plane starts, and every face's box:
        (lowest corner (F, 3), highest corner (F, 3))."""

        def make():
            order = radix_argsort(self.plane)
            starts = np.searchsorted(self.plane[order], np.arange(self.n_planes + 1))
            t = self.triangles
            lo = np.minimum(np.minimum(t[:, 0], t[:, 1]), t[:, 2])
            hi = np.maximum(np.maximum(t[:, 0], t[:, 1]), t[:, 2])
            return order, starts, (lo, hi)

        return self._cached("plane_index", make)

    def face_interactions(self, mode: int) -> np.ndarray:
        """(F,) the interaction column of each face's material for `mode` (0:
        specular, 1: diffuse), -1 for materials of single numbers; None without
        tables."""
        if self.spectra is None:
            return None
        return self.interaction[self.material, mode]

    @property
    def edge_table(self) -> EdgeTable:
        """The faces' :class:`~acousim.trace.world.mesh_index.EdgeTable` (over `faces`; the
        one :func:`build_world` found, not sorted again)."""
        return self._cached("edge_table", lambda: edge_table(self.faces))

    @property
    def vertex_groups(self) -> tuple[np.ndarray, np.ndarray]:
        """The vertices merged as trimesh's ``merge_vertices`` merges a triangle
        soup (equal to 1e-8 m; meshes of a scene may share vertices): the first
        vertex of every merged one (M,) and the merged one of every vertex (V,)
        (:func:`~acousim.trace.world.mesh_index.merged_vertex_ids`)."""
        return self._cached("vertex_groups", lambda: merged_vertex_ids(self.vertices))

    @property
    def n_planes(self) -> int:
        return self._cached("n_planes", lambda: int(self.plane.max()) + 1)

    @property
    def surface(self) -> np.ndarray:
        """(F,) surface id: the plane for planar faces, n_planes + the connected
        component for curved faces (one id per curved object).  Read-only."""
        return self._cached(
            "surface", lambda: np.where(self.curved, self.n_planes + self.component, self.plane)
        )

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


def _unreadable(path, exc: Exception) -> InputError:
    """The error for a mesh file its reader refused: "could not be read as" its
    format (by its extension), with the reader's reason."""
    fmt = Path(path).suffix.lstrip(".").upper() if isinstance(path, str | Path) else ""
    return InputError(f"could not be read as {fmt or 'a mesh'} ({exc})", file=_name(path))


def _no_faces(path) -> InputError:
    """The error for a mesh without faces: a file read as its format (by its
    extension) that gave none is not a mesh of that format (a text file named .stl
    reads as an empty STL)."""
    if not isinstance(path, str | Path):
        return InputError("mesh has no faces", file=_name(path))
    fmt = Path(path).suffix.lstrip(".").upper() or "a mesh"
    return InputError(f"could not be read as {fmt} (no faces found in it)", file=_name(path))


def _load(path, transform) -> object:
    """A mesh file or a ``trimesh.Trimesh`` (copied) placed by `transform` and
    cleaned (:func:`clean_mesh`), as a ``trimesh.Trimesh``."""
    import trimesh

    part = _load_part(path, transform)
    return trimesh.Trimesh(part.vertices, part.faces, process=False)


def _load_part(path, transform) -> MeshPart:
    import trimesh

    try:  # a trimesh.Trimesh in memory is never changed (copied to be moved)
        mesh = path if isinstance(path, trimesh.Trimesh) else read_mesh(path)
    except Exception as exc:  # trimesh raises many kinds
        raise _unreadable(path, exc) from None
    if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
        raise _no_faces(path)
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("mesh has NaN or inf vertices", file=_name(path))

    # checked before transforming: a product of huge numbers would overflow first
    T = np.asarray(transform, float)
    reach = float(np.abs(mesh.vertices).max()) * float(np.abs(T[:3, :3]).sum(axis=1).max())
    if not reach + float(np.abs(T[:3, 3]).max()) <= MAX_COORDINATE_M:
        raise InputError(
            f"mesh vertices reach beyond +-{MAX_COORDINATE_M:g} m once placed",
            file=_name(path),
        )
    if not trimesh.util.allclose(T, np.eye(4), 1e-8):  # trimesh's own test
        mesh = mesh.copy() if mesh is path else mesh
        mesh.apply_transform(T)
    part = clean_mesh(mesh)
    if len(part.faces) == 0:
        raise InputError("every face of the mesh is degenerate", file=_name(path))
    return part


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
        raise _unreadable(path, exc) from None
    if not isinstance(loaded, trimesh.Scene):
        if not hasattr(loaded, "faces") or len(loaded.faces) == 0:
            raise _no_faces(path)  # named by its file, not as the mesh in memory it became
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
        raise _no_faces(path)
    mesh = trimesh.util.concatenate(parts)
    mesh.merge_vertices()  # the groups of one file stay connected (face order kept)
    sizes = np.cumsum([0] + [len(p.faces) for p in parts])
    groups: dict[str, np.ndarray] = {}
    for i, answers in enumerate(names):
        for n in answers:
            groups.setdefault(n, np.zeros(len(mesh.faces), bool))[sizes[i] : sizes[i + 1]] = True
    return mesh, groups


def _material_of_faces(item: MeshItem, index: int, scene: Scene, names: list[str]):
    """The mesh of `item` (:class:`MeshPart`) and its faces' material indices into
    `names`."""
    if not item.materials:
        part = _load_part(item.mesh, item.transform)
        return part, np.full(len(part.faces), names.index(item.material.name))
    mesh, groups = face_groups(item.mesh, item.transform)
    part = MeshPart(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64), None, False)
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
    return part, mat


def build_world(scene: Scene) -> World:
    """Load, transform, clean and merge the meshes of a scene.

    Near-linear in the faces, on arrays (:func:`~acousim.trace.world.mesh_index.clean_mesh`
    cleans a mesh as trimesh would): coplanar faces are grouped by a hash of their
    plane (:func:`plane_ids`), the faces' edges in one sort of integer codes (kept:
    :attr:`World.edge_table`, for the diffracting edges too), the smooth corner
    normals are found for curved faces only, and the merged vertices and faces are
    kept for the ray caster (Embree's indexed mesh: no per-corner copies)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    materials = list(
        {
            m.name: m for item in scene.meshes for m in (item.material, *item.materials.values())
        }.values()
    )
    names = [m.name for m in materials]
    parts, mat_index = zip(
        *(_material_of_faces(item, i, scene, names) for i, item in enumerate(scene.meshes))
    )
    vertices, faces = parts[0].vertices, parts[0].faces
    if len(parts) > 1:
        start = np.cumsum([0] + [len(p.vertices) for p in parts])
        vertices = np.concatenate([p.vertices for p in parts])
        faces = np.concatenate([p.faces + s for p, s in zip(parts, start)])
    tri = parts[0].triangles if len(parts) == 1 else None  # the corners kept
    tri = vertices[faces] if tri is None else tri
    cross = [face_cross(p.vertices[p.faces]) if p.cross is None else p.cross for p in parts]
    normals, area = face_frames(cross[0] if len(cross) == 1 else np.concatenate(cross))
    offsets = np.einsum("fi,fi->f", normals, tri[:, 0])
    # curved faces: a neighbour at a small but non-zero dihedral angle
    curved = np.zeros(len(tri), bool)
    table = edge_table(faces)
    adj, shared = table.pairs, table.shared
    ang = _pair_angles(normals, adj)
    smooth = (ang > _FLAT_ANGLE) & (ang < np.deg2rad(CURVED_MAX_ANGLE_DEG))
    curved[adj[smooth].ravel()] = True
    curved |= smooth_patches(adj, ang, shared, vertices, len(tri))
    material = np.concatenate(mat_index)
    plane = plane_ids(normals, offsets, material if len(materials) > 1 else None)
    vn = np.empty((len(tri), 3, 3))
    vn[:] = normals[:, None, :]
    if curved.any():
        vn[curved] = _curved_corner_normals(tri, faces, normals, curved, (adj, ang, shared))
    # the connected parts (trimesh.graph.connected_component_labels' own call)
    links = coo_matrix((np.ones(len(adj), bool), adj.T), shape=(len(tri), len(tri)))
    component = connected_components(links, directed=False)[1]
    world = World(
        tri,
        normals,
        offsets,
        plane,
        curved,
        vn,
        material,
        tuple(materials),
        area,
        np.asarray(component),
        *_spectra(materials),
        vertices=vertices,
        faces=faces,
        owner=np.repeat(np.arange(len(mat_index)), [len(m) for m in mat_index]),
    )
    world._cached("edge_table", lambda: table)  # sorted once, kept for the edges
    if len(parts) == 1 and parts[0].distinct:  # no vertex to merge with another
        world._cached("vertex_groups", lambda: (np.arange(len(vertices)),) * 2)
    return world


def _pair_angles(normals: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(A,) angles (rad) between the unit normals (F, 3) of face pairs (A, 2), as
    trimesh's ``vector_angle`` computes them (the same numbers)."""
    dots = np.dot(normals[pairs[:, 0]] * normals[pairs[:, 1]], [1.0, 1.0, 1.0])
    return np.abs(np.arccos(np.clip(dots, -1.0, 1.0)))


def plane_ids(
    normals: np.ndarray, offsets: np.ndarray, material: np.ndarray | None = None
) -> np.ndarray:
    """(F,) plane id of every face: coplanar faces (normals rounded to 1e-6, offsets
    to 10 µm) share one; faces of another material (if `material` is given) are
    another plane.  Ids are numbered in the lexicographic order of (normal, offset,
    material), as ``np.unique(axis=0)`` of those rows would, but the F rows are
    grouped by a hash (one 1-D sort, checked for collisions) and only the distinct
    planes are sorted as rows."""
    key = np.column_stack([np.round(normals, 6), np.round(offsets, 5)])
    if material is not None:
        key = np.column_stack([key, material])
    key = np.ascontiguousarray(key + 0.0)  # -0.0 is 0.0, as np.unique compares them
    first, inverse = row_groups(key)
    _, rank = np.unique(key[first], axis=0, return_inverse=True)
    return rank.ravel()[inverse]


def smooth_patches(
    adjacency: np.ndarray, angles: np.ndarray, shared: np.ndarray, vertices: np.ndarray, n: int
) -> np.ndarray:
    """(n,) bool: faces of flat patches that belong to a curved surface.

    A patch is a set of faces joined by flat edges (dihedral angle at most 0.05°): a
    facet of a tessellated pipe or sphere, however finely it is subdivided.  It is
    curved when at least as much of its rim meets its neighbours smoothly (below
    ``CURVED_MAX_ANGLE_DEG``) as sharply: a pipe's facet, not a wall that one fillet
    touches.  So subdividing a curved surface's facets keeps them curved (only the
    faces along the facets' edges have a smooth neighbour)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    flat = angles <= _FLAT_ANGLE
    if not np.any(~flat & (angles < np.deg2rad(CURVED_MAX_ANGLE_DEG))):
        return np.zeros(n, bool)  # no smooth rim anywhere (a room, a box): none curved
    pairs = adjacency[flat]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, patch = connected_components(graph, directed=False)
    rough = np.flatnonzero(~flat)  # the patches' rims (few, however fine the mesh)
    length = np.linalg.norm(vertices[shared[rough, 0]] - vertices[shared[rough, 1]], axis=1)
    smooth = angles[rough] < np.deg2rad(CURVED_MAX_ANGLE_DEG)

    def rim(edges):
        return np.bincount(
            patch[adjacency[rough[edges]]].ravel(), np.repeat(length[edges], 2), patch.max() + 1
        )

    soft, hard = rim(smooth), rim(~smooth)
    return ((soft > 0) & (soft >= hard))[patch]


def _curved_corner_normals(tri, faces, normals, curved, adjacency) -> np.ndarray:
    """:func:`smooth_corner_normals` of the curved faces (C, 3, 3), computed on the
    faces that share a vertex with a curved face only: a corner's smoothing group
    holds faces around that one vertex, so its sums are those of the whole mesh, in
    the same order (flat faces keep their face normal).  adjacency: the face pairs,
    their dihedral angles and shared edges of :func:`face_adjacency`."""
    near = np.zeros(int(faces.max()) + 1, bool)
    near[faces[curved].ravel()] = True
    ring = near[faces].any(axis=1)
    index = np.full(len(tri), -1)
    index[ring] = np.arange(int(ring.sum()))
    adj, ang, shared = adjacency
    keep = ring[adj].all(axis=1)
    vn = smooth_corner_normals(
        tri[ring],
        faces[ring],
        normals[ring],
        index[adj[keep]],
        ang[keep],
        shared[keep],
    )
    return vn[curved[ring]]


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
