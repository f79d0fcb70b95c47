"""A mesh on arrays: integer groupings, each in one linear-time sort (a stable radix
argsort, equal rows by a hash, merged vertex ids, the edge table: which faces share
each edge, which edges belong to one face only), the faces' cross products, normals
and areas, and a mesh cleaned as trimesh cleans it (:func:`clean_mesh`).  Used to prepare a world
(:mod:`acousim.trace.world.build`) and to find its diffracting edges
(:mod:`acousim.trace.world.edges`) without rebuilding a trimesh mesh."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "EdgeTable",
    "MeshPart",
    "clean_mesh",
    "face_cross",
    "face_frames",
    "nondegenerate",
    "edge_table",
    "face_adjacency",
    "merged_vertex_ids",
    "radix_argsort",
    "row_groups",
]

#: vertices equal after rounding to this many decimals (of a metre) are one vertex,
#: as trimesh's ``merge_vertices`` has it (``trimesh.constants.tol.merge`` = 1e-8)
MERGE_DIGITS = 8


def radix_argsort(code: np.ndarray) -> np.ndarray:
    """A stable argsort of non-negative integers (n,), 16 bits a pass (numpy's radix
    sort of 16-bit keys): linear in n, for the long integer columns of a mesh."""
    code = np.asarray(code)
    order = np.arange(len(code))
    top, shift = int(code.max(initial=0)), 0
    while True:
        key = ((code[order] >> shift) & 0xFFFF).astype(np.uint16)
        order = order[np.argsort(key, kind="stable")]
        shift += 16
        if top >> shift == 0:
            return order


def row_groups(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equal rows of `key` (n, k) of 8-byte numbers (floats compared by their bytes:
    make -0.0 0.0 first): the first row of every group (G,) and the group of every
    row (n,), groups in no particular order.  One 1-D sort of a hash of each row,
    checked for collisions (then the rows themselves are sorted)."""
    key = np.ascontiguousarray(key)
    words = key.view(np.uint64).reshape(len(key), -1)
    code = np.zeros(len(key), np.uint64)
    with np.errstate(over="ignore"):
        for j in range(words.shape[1]):
            code = (code ^ words[:, j]) * np.uint64(0x100000001B3)
            code ^= code >> np.uint64(29)
    # np.unique(code, return_index=True, return_inverse=True), the same numbers
    order = np.argsort(code, kind="stable")
    code = code[order]
    new = np.concatenate([[True], code[1:] != code[:-1]])
    inverse = np.empty(len(key), np.intp)
    if new.all():  # distinct hashes: distinct rows
        inverse[order] = np.arange(len(key))
        return order, inverse
    inverse[order] = np.cumsum(new) - 1
    first = order[new]
    if not np.array_equal(key[first][inverse], key):  # a hash collision
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return first, inverse.ravel()


def merged_vertex_ids(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) (m) merged as trimesh's ``merge_vertices`` merges them (equal
    after rounding to :data:`MERGE_DIGITS` decimals): the first vertex of every merged
    vertex (M,) and the merged vertex of every vertex (V,)."""
    key = np.round(np.asarray(vertices, float) * 10**MERGE_DIGITS).astype(np.int64)
    return row_groups(key)


@dataclass(frozen=True, eq=False)
class EdgeTable:
    """The edges of a mesh of F faces (vertex indices).

    pairs (A, 2): the faces sharing an edge of exactly two faces (ascending in each
    row); shared (A, 2): that edge's vertices (ascending); same_way (A,) bool: both
    faces run along the edge in the same direction (faces on one side of it if their
    normals agree: a fold; a consistently wound mesh has none); rim_face (R,) and
    rim_edge (R, 2): the face and vertices (ascending) of every edge of one face only,
    in the order of the faces.  Edges of three faces or more are in neither."""

    pairs: np.ndarray
    shared: np.ndarray
    same_way: np.ndarray
    rim_face: np.ndarray
    rim_edge: np.ndarray


def edge_table(faces: np.ndarray) -> EdgeTable:
    """The :class:`EdgeTable` of faces (F, 3) (vertex indices), in one sort of the
    3 F edges' integer codes (a vertex pair as one integer; few copies of 3 F
    integers: a finely tessellated mesh's memory is first touched here)."""
    f = np.asarray(faces, np.int64)
    u, v = f.ravel(), f[:, [1, 2, 0]].ravel()  # edge 3 i + j of face i: corners j, j + 1
    n = int(u.max(initial=0)) + 1
    code = np.minimum(u, v)
    code *= n
    code += np.maximum(u, v)
    forward = u < v
    del v
    order, code = _sorted_codes(code, n * n)
    forward = forward[order]
    new = np.concatenate([[True], code[1:] != code[:-1], [True]])  # a group starts here
    starts = np.flatnonzero(new)
    size = np.diff(starts)
    two = starts[:-1][size == 2]
    a, b = order[two] // 3, order[two + 1] // 3
    keep = a != b  # a degenerate face's two halves of one edge are no pair
    two = two[keep]
    one = np.sort(order[starts[:-1][size == 1]])  # the rims, in the order of the faces
    face, corner = np.divmod(one, 3)
    end = np.sort(np.column_stack([f[face, corner], f[face, (corner + 1) % 3]]), axis=1)
    return EdgeTable(
        np.column_stack([a[keep], b[keep]]),  # a < b: the sort is stable
        np.column_stack([code[two] // n, code[two] % n]),
        forward[two] == forward[two + 1],
        face,
        end,
    )


def _sorted_codes(code: np.ndarray, top: int) -> tuple[np.ndarray, np.ndarray]:
    """A stable argsort of non-negative integers `code` (n,) below `top`, and the
    sorted codes (`code` is consumed: sorted in place).  When a code and its index
    fit in 63 bits, the two are sorted as one integer (numpy's stable sort of
    values, quick on a mesh's mostly ordered codes); else :func:`radix_argsort`."""
    shift = max(len(code) - 1, 1).bit_length()
    if (top - 1).bit_length() + shift <= 63:
        code <<= shift
        code |= np.arange(len(code))
        code.sort(kind="stable")
        order = code & ((1 << shift) - 1)
        code >>= shift
        return order, code
    order = radix_argsort(code)
    return order, code[order]


def face_adjacency(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces that share an edge (an edge of exactly two faces), as trimesh's
    ``face_adjacency`` finds them: the pairs (A, 2), each in ascending order, and
    their shared edges (A, 2) as ascending vertex ids (:func:`edge_table`).
    faces (F, 3) vertex indices."""
    table = edge_table(faces)
    return table.pairs, table.shared


@dataclass(frozen=True, eq=False)
class MeshPart:
    """One mesh of a scene, loaded and cleaned: vertices (V, 3) m, faces (F, 3),
    the faces' cross products (F, 3) (:func:`face_cross`; None: not computed),
    whether no two vertices are equal to 1e-8 m (merged by position) and the
    faces' corners (F, 3, 3) m (None: not computed)."""

    vertices: np.ndarray
    faces: np.ndarray
    cross: np.ndarray | None
    distinct: bool
    triangles: np.ndarray | None = None


def face_cross(tri: np.ndarray) -> np.ndarray:
    """(F, 3) the cross products (b - a) x (c - b) of triangles (F, 3, 3) [a, b, c],
    component by component (the same numbers as trimesh's ``triangles_cross``)."""
    u, w = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 1]
    out = np.empty((len(tri), 3))
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        np.subtract(u[:, j] * w[:, k], u[:, k] * w[:, j], out=out[:, i])
    return out


def nondegenerate(tri: np.ndarray, height_m: float, cross: np.ndarray) -> np.ndarray:
    """(F,) bool: triangles (F, 3, 3) whose heights over both edges from the first
    corner exceed `height_m` (m), as trimesh's ``nondegenerate_faces`` tells them
    (an edge of 1e-8 m or less has height 0); cross (F, 3): their :func:`face_cross`."""
    area2 = np.sqrt((cross**2).sum(axis=1))  # twice the area
    ok = np.ones(len(tri), bool)
    for corner in (1, 2):
        e = tri[:, corner] - tri[:, 0]
        length = (e**2).sum(axis=1) ** 0.5
        long = length > 1e-8
        height = np.zeros(len(tri))
        height[long] = area2[long] / length[long]
        ok &= height > height_m
    return ok


def face_frames(cross: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (F, 3) (zero for a face without area) and areas (F,) (m²) of
    triangles [a, b, c] from their cross products (F, 3) (b - a) x (c - b)
    (:func:`face_cross`), computed as trimesh's ``face_normals`` and ``area_faces``
    compute them (the same numbers)."""
    norm = np.sqrt(np.dot(cross * cross, [1.0, 1.0, 1.0]))
    area = np.sqrt((cross**2).sum(axis=1)) / 2.0
    valid = norm > 1e-13  # trimesh.util.TOL_ZERO
    unit = np.zeros_like(cross)
    unit[valid] = cross[valid] * (norm[valid] ** -1)[:, None]
    return unit, area


def _first_of_rows(rows: np.ndarray) -> np.ndarray:
    """The first of every group of equal rows of non-negative integers (n, 3), in
    order.  A row packed into one integer when it fits (exact); most meshes repeat
    no face, which one sort of the values tells."""
    bits = int(rows.max(initial=0)).bit_length()
    if 3 * bits > 63:
        return np.sort(row_groups(rows)[0])
    code = (rows[:, 0] << (2 * bits)) | (rows[:, 1] << bits) | rows[:, 2]
    ordered = np.sort(code)
    if not (ordered[1:] == ordered[:-1]).any():
        return np.arange(len(rows))
    return np.sort(np.unique(code, return_index=True)[1])


def clean_mesh(mesh) -> MeshPart:
    """The vertices (V, 3) and faces (F, 3) of a trimesh mesh cleaned as its
    ``merge_vertices``, ``nondegenerate_faces(height=1e-9)``, ``unique_faces`` and
    ``remove_unreferenced_vertices`` clean it (the same arrays), on arrays: vertices
    equal to 1e-8 m merged (:func:`merged_vertex_ids`; trimesh's own merge for a
    mesh whose vertices also carry texture coordinates or normals), faces with a
    height of 1e-9 m or less dropped, then repeated faces, then unused vertices.
    `mesh` itself is not changed."""
    uv = getattr(mesh.visual, "uv", None) if mesh.visual.kind == "texture" else None
    distinct = uv is None and "vertex_normals" not in mesh._cache.cache
    if not distinct:
        mesh = mesh.copy()  # the caller's mesh is not changed
        mesh.merge_vertices()
        vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
    else:
        vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
        used = np.flatnonzero(np.bincount(faces.ravel(), minlength=len(vertices)))
        first, group = merged_vertex_ids(vertices[used])
        rank = np.empty(len(first), np.int64)  # groups numbered by first occurrence
        order = np.argsort(first)
        rank[order] = np.arange(len(first))
        into = np.zeros(len(vertices), np.int64)
        into[used] = rank[group]
        vertices, faces = vertices[used[first[order]]], into[faces]
    tri = vertices[faces]
    cross = face_cross(tri)
    keep = np.flatnonzero(nondegenerate(tri, height_m=1e-9, cross=cross))
    f = faces[keep]
    low = np.minimum(np.minimum(f[:, 0], f[:, 1]), f[:, 2])
    high = np.maximum(np.maximum(f[:, 0], f[:, 1]), f[:, 2])
    keep = keep[_first_of_rows(np.column_stack([low, f.sum(axis=1) - low - high, high]))]
    if len(keep) < len(faces):
        faces, cross, tri = faces[keep], cross[keep], tri[keep]
    used = np.zeros(len(vertices), bool)
    used[faces] = True
    into = np.cumsum(used) - 1
    return MeshPart(vertices[used], into[faces], cross, distinct, tri)
