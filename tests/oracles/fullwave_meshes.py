"""Triangle meshes for the full-wave cases, built in numpy (no mesher needed).

Every function returns ``(vertices (V, 3) m, triangles (F, 3) int)``. Closed surfaces
are oriented with outward normals (counter-clockwise seen from outside); bempp's
Burton-Miller formulation relies on it. Elements are right triangles from a structured
quad grid; ``h`` (m) is the largest quad side.
"""

from __future__ import annotations

import numpy as np


def _quad_grid(n_u: int, n_v: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit-square grid: (u, v) in [0, 1]^2 at (n_u + 1) x (n_v + 1) points, and its
    triangles (counter-clockwise in the u-v plane), diagonals alternating."""
    u, v = np.meshgrid(np.linspace(0, 1, n_u + 1), np.linspace(0, 1, n_v + 1), indexing="ij")
    idx = np.arange(u.size).reshape(u.shape)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    flip = ((np.arange(n_u)[:, None] + np.arange(n_v)[None, :]) % 2).ravel().astype(bool)
    t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    t2 = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
    return np.stack([u.ravel(), v.ravel()], 1), np.concatenate([t1, t2])


def _merge(vertices: np.ndarray, triangles: np.ndarray, tol: float):
    """Weld vertices closer than tol (shared edges of separately built faces)."""
    key = np.round(vertices / tol).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return vertices[first], inverse.ravel()[triangles]


def box(size_m: tuple[float, float, float], h_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed rigid box centred at the origin, sides size_m (x, y, z) in m."""
    size = np.asarray(size_m, float)
    verts, tris, offset = [], [], 0
    for axis in range(3):
        j, m = [a for a in range(3) if a != axis]
        (uv, t) = _quad_grid(
            max(1, int(np.ceil(size[j] / h_m))), max(1, int(np.ceil(size[m] / h_m)))
        )
        for sign in (1.0, -1.0):
            p = np.zeros((len(uv), 3))
            p[:, axis] = sign * size[axis] / 2
            p[:, j] = (uv[:, 0] - 0.5) * size[j]
            p[:, m] = (uv[:, 1] - 0.5) * size[m]
            # (e_j, e_m, e_axis) is right-handed for axis 0, 1, 2 with j < m except axis 1
            right_handed = axis != 1
            outward_ccw = right_handed == (sign > 0)
            verts.append(p)
            tris.append((t if outward_ccw else t[:, ::-1]) + offset)
            offset += len(p)
    return _merge(np.concatenate(verts), np.concatenate(tris), 1e-6 * h_m)


def sphere(radius_m: float, h_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed sphere centred at the origin: a cube whose faces are divided at equal
    angles (so elements are nearly uniform), projected onto the sphere."""
    n = int(np.ceil(np.pi / 2 * radius_m / h_m))
    v, t = box((2.0, 2.0, 2.0), 2.0 / n)
    v = np.tan(v * np.pi / 4)  # equal-angle spacing on each face
    return radius_m * v / np.linalg.norm(v, axis=1, keepdims=True), t


def screen(side_m: float, h_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Square zero-thickness plate in the plane x = 0, centred at the origin (an open
    surface: rims are boundary edges)."""
    n = max(1, int(np.ceil(side_m / h_m)))
    uv, t = _quad_grid(n, n)
    p = np.zeros((len(uv), 3))
    p[:, 1:] = (uv - 0.5) * side_m
    return p, t


def rotate_z(vertices: np.ndarray, angle_rad: float) -> np.ndarray:
    """Vertices turned by angle_rad about the z axis (through the origin)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return vertices @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T


def outward_volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Signed enclosed volume (m^3, > 0 when the normals point outward)."""
    a, b, c = (vertices[triangles[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)
