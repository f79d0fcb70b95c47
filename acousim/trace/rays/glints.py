"""Stage 2b of the tracer: the specular points (glints) of curved surfaces, found
deterministically, as the image method finds those of planes.

A tessellated curved surface (sphere, pipe, pole) is read as the smooth surface its
corner normals describe: on a face, the point ``x(b) = sum b_i p_i`` has the normal
``n(b) = normalise(sum b_i n_i)`` (barycentric b).  Its first-order echo in geometric
optics comes from the points where that normal bisects the directions to the emitter
and to the receiver (the path length is stationary there), with the amplitude that
the surface's curvature gives the reflected wavefront.  Rays are not needed to find
them, so a 2 cm sphere or a 1 cm pole echoes at the default ray budget, and the
echo does not depend on ``lobe_deg`` (which now shapes only the multiply reflected
contributions of curved surfaces, stage 4).

1. Candidates: curved faces with a corner normal towards the sensor, whose normals
   can bisect the directions to the sensor (a cone test: most faces of an object
   are left out before the search).
2. On each, Gauss-Newton on (b_1, b_2) for ``n(b) = h(x(b))``, h the unit bisector of
   the directions to emitter and receiver; keep solutions inside the face (within a
   tolerance), one per point (neighbouring faces find the same point on their edge).
3. Within reach: the whole path within ``max_path_m``, leaving the emitter within
   the beam, and visible (shadow rays to the emitter and to the receiver).
4. Amplitude: the incident spherical wave (curvature 1/r1) reflected by a surface of
   shape operator S (from the corner normals of its face) has the curvature matrix
   ``K = I / r1 + 2 S`` (near-normal incidence: emitter and receiver a few cm apart);
   at the receiver, r2 further, the pressure is ``R / r1 / sqrt(|det(I + r2 K)|)``, R
   the face's specular reflection factor ``reflection * sqrt(1 - diffuse)``.  A
   sphere of radius a at distance r from its surface: ``a / (2 r (r + a))``; a
   cylinder broadside: ``sqrt(a / (a + r)) / (2 r)``.  Near a caustic of a concave
   surface geometric optics fails: each factor is capped at ``CAUSTIC_CAP``.
"""

from __future__ import annotations

import numpy as np

from acousim.trace.paths import KIND, TracedPaths
from acousim.trace.world.build import World, radix_argsort, row_groups
from acousim.trace.world.embree import RayCaster
from processing.base.kernels import optional_kernel

__all__ = ["glints", "curved_groups", "CAUSTIC_CAP"]

#: largest gain of one principal direction of a focusing (concave) surface
CAUSTIC_CAP = 3.0
_ITERATIONS = 20
_HALVINGS = 8
_STEP = 1e-6  # finite-difference step in barycentric coordinates
_INSIDE = 1e-4  # barycentric tolerance for "on the face" (a point on an edge)
_CONVERGED = 1e-7  # |n - h| at a specular point


def _normal(world: World, f: np.ndarray, b: np.ndarray) -> np.ndarray:
    vn = world.vertex_normals[f]
    n = vn[:, 0] + b[:, :1] * (vn[:, 1] - vn[:, 0]) + b[:, 1:] * (vn[:, 2] - vn[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _point(world: World, f: np.ndarray, b: np.ndarray) -> np.ndarray:
    p = world.triangles[f]
    return p[:, 0] + b[:, :1] * (p[:, 1] - p[:, 0]) + b[:, 1:] * (p[:, 2] - p[:, 0])


def _bisector(x: np.ndarray, emitter: np.ndarray, receiver: np.ndarray) -> np.ndarray:
    ue = emitter - x
    ur = receiver - x
    h = ue / np.linalg.norm(ue, axis=1, keepdims=True) + ur / np.linalg.norm(
        ur, axis=1, keepdims=True
    )
    return h / np.linalg.norm(h, axis=1, keepdims=True)


def _residual(world, f, b, emitter, receiver) -> np.ndarray:
    return _normal(world, f, b) - _bisector(_point(world, f, b), emitter, receiver)


def _norm(v: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(v, axis=1, keepdims=True)`` of rows (K, 3): the same sums,
    without its checks."""
    return np.sqrt(np.add.reduce(v * v, axis=1, keepdims=True))


class _Faces:
    """Faces as the search reads them, gathered once: the corner normals and the
    corners, each as (corner 0, corner 1 - corner 0, corner 2 - corner 0) (K, 3):
    :meth:`residual` is :func:`_residual`, the same operations on the same values."""

    def __init__(self, normals: tuple, points: tuple) -> None:
        self.normals, self.points = normals, points

    @classmethod
    def of(cls, world: World, f: np.ndarray) -> _Faces:
        vn, p = world.vertex_normals[f], world.triangles[f]
        return cls(
            (vn[:, 0], vn[:, 1] - vn[:, 0], vn[:, 2] - vn[:, 0]),
            (p[:, 0], p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
        )

    def take(self, rows: np.ndarray) -> _Faces:
        return _Faces(tuple(a[rows] for a in self.normals), tuple(a[rows] for a in self.points))

    def residual(self, b: np.ndarray, emitter: np.ndarray, receiver: np.ndarray) -> np.ndarray:
        """(K, 3) the normal at barycentric `b` (K, 2) less the bisector there."""
        (n0, n1, n2), (p0, p1, p2) = self.normals, self.points
        b1, b2 = b[:, :1], b[:, 1:]
        n = n0 + b1 * n1 + b2 * n2
        x = p0 + b1 * p1 + b2 * p2
        ue, ur = emitter - x, receiver - x
        h = ue / _norm(ue) + ur / _norm(ur)
        return n / _norm(n) - h / _norm(h)


#: curved faces are grouped for the cone test by connected surface, cell of this size
#: (m) and normal (rounded to quarters of its components)
_GROUP_CELL_M = 0.05


def curved_groups(world: World):
    """The curved faces (ascending) grouped once per world: the faces by group, where
    each group starts, and per group a ball (centre, radius) holding its faces, the
    mean normal and the largest angle of a face normal from it, and the largest
    corner spread and extent of its faces (as step 1 uses them)."""

    def make():
        f = np.flatnonzero(world.curved)
        if f.size == 0:
            z = np.zeros(0)
            return f, np.zeros(1, int), np.zeros((0, 3)), z, np.zeros((0, 3)), z, z, z
        centre = world.triangles[f].mean(axis=1)
        nf = world.normals[f]
        key = np.column_stack(
            [
                world.component[f],
                np.floor(centre / _GROUP_CELL_M),
                np.round(nf * 4),
            ]
        ).astype(np.int64)
        group = row_groups(key)[1]
        order = radix_argsort(group)
        starts = np.searchsorted(group[order], np.arange(group.max() + 2))
        count = np.bincount(group)
        mid = np.stack([np.bincount(group, centre[:, k]) for k in range(3)], axis=1)
        mid /= count[:, None]
        extent = np.linalg.norm(world.triangles[f] - centre[:, None], axis=2).max(axis=1)
        radius = np.zeros(len(count))
        np.maximum.at(radius, group, np.linalg.norm(centre - mid[group], axis=1) + extent)
        mean = np.stack([np.bincount(group, nf[:, k]) for k in range(3)], axis=1)
        mean /= np.maximum(np.linalg.norm(mean, axis=1, keepdims=True), 1e-300)
        off = np.zeros(len(count))
        cos_n = np.clip(np.einsum("ij,ij->i", nf, mean[group]), -1, 1)
        np.maximum.at(off, group, np.arccos(cos_n))
        cos_corner = np.einsum("kij,kj->ki", world.vertex_normals[f], nf).min(axis=1)
        spread = np.zeros(len(count))
        np.maximum.at(spread, group, np.arccos(np.clip(cos_corner, -1, 1)))
        ext = np.zeros(len(count))
        np.maximum.at(ext, group, extent)
        return f[order], starts, mid, radius, mean, off, spread, ext

    return world._cached("glint_groups", make)


def _near_bisecting(world: World, emitter: np.ndarray, receiver: np.ndarray) -> np.ndarray:
    """The curved faces (ascending) of the groups in which a face may pass step 1's
    cone test: a group is left out when even its best face cannot (the angle between
    the bisector at the group's centre and its mean normal, less how far the
    bisector turns within its ball and its normals spread, exceeds the largest corner
    spread plus 1.5 times the largest angle a face subtends, and a margin).  The
    faces kept are then tested one by one, as before."""
    faces, starts, mid, radius, mean, off, spread, ext = curved_groups(world)
    if len(mid) == 0:
        return faces
    h = _bisector(mid, emitter, receiver)
    d_e = np.linalg.norm(emitter - mid, axis=1)
    d_r = np.linalg.norm(receiver - mid, axis=1)
    s = np.linalg.norm((emitter - mid) / d_e[:, None] + (receiver - mid) / d_r[:, None], axis=1)
    near = np.minimum(d_e, d_r) <= 2 * radius
    turn = 2 * radius / np.maximum(d_e - radius, 1e-300) + 2 * radius / np.maximum(
        d_r - radius, 1e-300
    )  # how far the sum of the two unit vectors moves within the ball
    dh = np.where(near | (turn >= s), np.pi, np.arcsin(np.minimum(1.0, turn / s)))
    subtended = np.where(
        d_e > radius, np.arcsin(np.minimum(1.0, ext / np.maximum(d_e - radius, 1e-300))), np.pi
    )
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", h, mean), -1, 1))
    keep = angle - 1.5 * dh - off <= spread + 1.5 * subtended + 2e-3
    return np.sort(faces[np.repeat(keep, np.diff(starts))])


def _shape_operator(world: World, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per face: a tangent basis (K, 2, 3) and the shape operator S (K, 2, 2) in it,
    from the change of the corner normals along the face's edges (dn = S dp)."""
    p = world.triangles[f]
    vn = world.vertex_normals[f]
    t1 = p[:, 1] - p[:, 0]
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(world.normals[f], t1)
    basis = np.stack([t1, t2], axis=1)
    edges = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)  # (K, 3, 2)
    dn = np.stack([vn[:, 1] - vn[:, 0], vn[:, 2] - vn[:, 0]], axis=2)
    E = basis @ edges  # (K, 2, 2): edges in the tangent basis, as columns
    D = basis @ dn
    S = D @ np.linalg.inv(E)
    return basis, (S + np.swapaxes(S, 1, 2)) / 2


def glints(
    world: World,
    caster: RayCaster,
    emitter: np.ndarray,
    receiver: np.ndarray,
    axis: np.ndarray,
    beam_rad: float,
    max_path_m: float,
) -> TracedPaths:
    """First-order geometric-optics echoes of the curved surfaces (kind "scatter")."""
    # 1. candidate faces; 2. the specular point on each, one per point
    f = _candidates(world, emitter, receiver)
    if f.size == 0:
        return TracedPaths.empty()
    f, b = _specular_points(world, f, emitter, receiver)
    x = _point(world, f, b)
    keep = _distinct(x, caster.tolerance_m)  # one per point
    f, b, x = f[keep], b[keep], x[keep]
    # 3. within reach, within the beam, visible from the emitter and the receiver
    r1 = np.linalg.norm(emitter - x, axis=1)
    r2 = np.linalg.norm(receiver - x, axis=1)
    dep = (x - emitter) / r1[:, None]
    ok = (r1 + r2 <= max_path_m) & (dep @ axis >= np.cos(beam_rad) - 1e-12)
    n = _normal(world, f, b)
    for end in (emitter, receiver):
        idx = np.flatnonzero(ok)
        start = x[idx] + caster.offset_m * n[idx]
        d = end - start
        L = np.linalg.norm(d, axis=1)
        t, hit = caster.first_hit(start, d)
        ok[idx[(hit >= 0) & (t < L - caster.tolerance_m)]] = False
    f, x, r1, r2, dep = f[ok], x[ok], r1[ok], r2[ok], dep[ok]
    if f.size == 0:
        return TracedPaths.empty()
    # 4. amplitude from the curvature of the reflected wavefront
    _, S = _shape_operator(world, f)
    K = np.eye(2) / r1[:, None, None] + 2 * S
    k = np.linalg.eigvalsh(K)  # (K, 2) principal curvatures of the reflected wave
    factor = np.minimum(1 / np.sqrt(np.abs(1 + r2[:, None] * k)), CAUSTIC_CAP)
    R = world.face_values("reflection")[f] * np.sqrt(1 - world.face_values("diffuse")[f])
    amp = R / r1 * factor.prod(axis=1)
    n_g = f.size
    counts = None
    if world.spectra is not None:  # the specular interaction of the face's material
        column = world.face_interactions(0)[f]
        counts = np.zeros((n_g, world.n_interactions), int)
        counts[np.flatnonzero(column >= 0), column[column >= 0]] = 1
    return TracedPaths(
        x, r1, amp * r2, x, np.ones(n_g, int), np.full(n_g, KIND["scatter"]), dep, counts
    )


def _candidates(world: World, emitter: np.ndarray, receiver: np.ndarray) -> np.ndarray:
    """Step 1 of :func:`glints`: the curved faces (indices) with a corner normal
    towards the sensor whose normals can bisect: the normal at the specular point
    lies within the cone of the corner normals (half-angle `spread` around the face
    normal), and the bisector there within the angle the face subtends of the
    bisector at its centre."""
    f = _near_bisecting(world, emitter, receiver)
    if f.size == 0:
        return f
    towards = np.einsum("kij,kij->ki", world.vertex_normals[f], emitter - world.triangles[f])
    f = f[(towards > 0).any(axis=1)]
    centre = world.triangles[f].mean(axis=1)
    h = _bisector(centre, emitter, receiver)
    nf = world.normals[f]
    cos_corner = np.einsum("kij,kj->ki", world.vertex_normals[f], nf).min(axis=1)
    spread = np.arccos(np.clip(cos_corner, -1, 1))
    extent = np.linalg.norm(world.triangles[f] - centre[:, None], axis=2).max(axis=1)
    dist = np.linalg.norm(emitter - centre, axis=1)
    subtended = np.arcsin(np.minimum(1.0, extent / np.maximum(dist, 1e-12)))
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", h, nf), -1, 1))
    f = f[angle <= spread + 1.5 * subtended + 1e-3]
    return f


def _specular_points(world: World, f: np.ndarray, emitter: np.ndarray, receiver: np.ndarray):
    """Step 2 of :func:`glints`: the faces `f` that hold a specular point and its
    barycentric coordinates (K, 2); compiled (:mod:`.glint_kernel`: face by face, the
    same iteration) or, without numba, in numpy (:func:`_specular_points_numpy`)."""
    kernel = optional_kernel("acousim.trace.rays.glint_kernel", "specular_points")
    if kernel is None:
        return _specular_points_numpy(world, f, emitter, receiver)
    b = np.empty((f.size, 2))
    ok = kernel(
        world.vertex_normals,
        world.triangles,
        np.ascontiguousarray(f, np.int64),
        np.ascontiguousarray(emitter, float),
        np.ascontiguousarray(receiver, float),
        _ITERATIONS,
        _HALVINGS,
        _STEP,
        _CONVERGED,
        _INSIDE,
        b,
    )
    return f[ok], b[ok]


def _specular_points_numpy(
    world: World, f: np.ndarray, emitter: np.ndarray, receiver: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_specular_points` in numpy, all faces at once."""
    # 2. Gauss-Newton for the specular point on each face, steps halved until the
    #    residual drops (long faces, such as a pipe's, overshoot with full steps);
    #    a face leaves the search once converged, stuck, or far outside its edges
    faces = _Faces.of(world, f)
    b = np.full((f.size, 2), 1 / 3)
    r = faces.residual(b, emitter, receiver)
    live = np.arange(f.size)
    for it in range(_ITERATIONS):
        size = np.linalg.norm(r[live], axis=1)
        bary = np.column_stack([1 - b[live].sum(axis=1), b[live]])
        outside = (bary.min(axis=1) < -0.25) & (it >= 3)
        live = live[(size >= _CONVERGED) & ~outside]
        if live.size == 0:
            break
        fl, bl, rl = faces.take(live), b[live], r[live]
        J = np.stack(
            [
                (fl.residual(bl + [_STEP, 0], emitter, receiver) - rl) / _STEP,
                (fl.residual(bl + [0, _STEP], emitter, receiver) - rl) / _STEP,
            ],
            axis=2,
        )  # (K, 3, 2)
        JtJ = np.swapaxes(J, 1, 2) @ J + 1e-12 * np.eye(2)
        delta = np.linalg.solve(JtJ, (np.swapaxes(J, 1, 2) @ rl[:, :, None]))[:, :, 0]
        size = np.linalg.norm(rl, axis=1)
        todo = np.arange(live.size)
        scale = 1.0
        for _ in range(_HALVINGS):
            trial = np.clip(bl[todo] - scale * delta[todo], -0.5, 1.5)
            r1 = (fl if todo.size == live.size else fl.take(todo)).residual(
                trial, emitter, receiver
            )
            better = np.linalg.norm(r1, axis=1) <= size[todo]
            b[live[todo[better]]], r[live[todo[better]]] = trial[better], r1[better]
            todo = todo[~better]
            if todo.size == 0:
                break
            scale /= 2
        stuck = np.zeros(f.size, bool)
        stuck[live[todo]] = True
        live = live[~stuck[live]]
    res = np.linalg.norm(faces.residual(b, emitter, receiver), axis=1)
    bary = np.column_stack([1 - b.sum(axis=1), b])
    ok = (res < _CONVERGED) & (bary.min(axis=1) >= -_INSIDE)
    return f[ok], b[ok]


def _distinct(x: np.ndarray, tol: float) -> np.ndarray:
    """Which of the points `x` (K, 3) to keep: one per point (neighbours meet on
    their shared edge), within `tol` (m)."""
    keep = np.ones(len(x), bool)
    for i in range(len(x)):
        if keep[i]:
            same = np.linalg.norm(x[i + 1 :] - x[i], axis=1) <= tol
            keep[i + 1 :][same] = False
    return keep
