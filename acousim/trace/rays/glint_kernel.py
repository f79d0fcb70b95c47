"""Compiled step 2 of :func:`acousim.trace.rays.glints.glints` (numba; optional:
without numba the search runs in numpy, :func:`.glints._specular_points_numpy`).

Per candidate face, on its own: Gauss-Newton on the barycentric (b_1, b_2) for the
smooth normal ``n(b)`` equal to the unit bisector ``h(x(b))`` of the directions to
the emitter and the receiver, the Jacobian by forward differences, each step halved
until the residual drops; the same iteration as the numpy search, face by face
(each face's iterates depend on that face alone), its 2 x 2 normal equations solved
in closed form rather than by LAPACK (the same solution, to rounding).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def _residual(vn, tri, f, b1, b2, e, r, out):  # pragma: no cover - compiled
    """``out`` (3,): the smooth normal of face `f` at (b1, b2) less the unit bisector
    there (vn: corner normals (F, 3, 3), tri: corners (F, 3, 3))."""
    nx = vn[f, 0, 0] + b1 * (vn[f, 1, 0] - vn[f, 0, 0]) + b2 * (vn[f, 2, 0] - vn[f, 0, 0])
    ny = vn[f, 0, 1] + b1 * (vn[f, 1, 1] - vn[f, 0, 1]) + b2 * (vn[f, 2, 1] - vn[f, 0, 1])
    nz = vn[f, 0, 2] + b1 * (vn[f, 1, 2] - vn[f, 0, 2]) + b2 * (vn[f, 2, 2] - vn[f, 0, 2])
    x = tri[f, 0, 0] + b1 * (tri[f, 1, 0] - tri[f, 0, 0]) + b2 * (tri[f, 2, 0] - tri[f, 0, 0])
    y = tri[f, 0, 1] + b1 * (tri[f, 1, 1] - tri[f, 0, 1]) + b2 * (tri[f, 2, 1] - tri[f, 0, 1])
    z = tri[f, 0, 2] + b1 * (tri[f, 1, 2] - tri[f, 0, 2]) + b2 * (tri[f, 2, 2] - tri[f, 0, 2])
    ex, ey, ez = e[0] - x, e[1] - y, e[2] - z
    rx, ry, rz = r[0] - x, r[1] - y, r[2] - z
    le = math.sqrt(ex * ex + ey * ey + ez * ez)
    lr = math.sqrt(rx * rx + ry * ry + rz * rz)
    hx, hy, hz = ex / le + rx / lr, ey / le + ry / lr, ez / le + rz / lr
    lh = math.sqrt(hx * hx + hy * hy + hz * hz)
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    out[0] = nx / ln - hx / lh
    out[1] = ny / ln - hy / lh
    out[2] = nz / ln - hz / lh


@njit(cache=True, nogil=True, inline="always")
def _size(v):  # pragma: no cover - compiled
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True, nogil=True)
def specular_points(
    vn, tri, faces, emitter, receiver, iterations, halvings, step, converged, inside, b_out
):  # pragma: no cover - compiled
    """(K,) bool: whether face ``faces[i]`` holds a specular point, its barycentric
    (b_1, b_2) written to ``b_out[i]`` (K, 2): at most `iterations` Gauss-Newton
    steps from the centroid, each halved up to `halvings` times until the residual
    |n - h| drops (a face stuck, or past a quarter outside its edges after three
    steps, leaves the search); kept if the residual ends below `converged` and no
    barycentric coordinate is below -`inside`."""
    K = faces.shape[0]
    ok = np.zeros(K, np.bool_)
    r = np.empty(3)
    r1 = np.empty(3)
    j1 = np.empty(3)
    j2 = np.empty(3)
    for i in range(K):
        f = faces[i]
        b1, b2 = 1 / 3, 1 / 3
        _residual(vn, tri, f, b1, b2, emitter, receiver, r)
        for it in range(iterations):
            size = _size(r)
            least = min(1 - (b1 + b2), min(b1, b2))
            if size < converged or (least < -0.25 and it >= 3):
                break
            _residual(vn, tri, f, b1 + step, b2, emitter, receiver, j1)
            _residual(vn, tri, f, b1, b2 + step, emitter, receiver, j2)
            a11 = a12 = a22 = g1 = g2 = 0.0
            for c in range(3):
                d1 = (j1[c] - r[c]) / step
                d2 = (j2[c] - r[c]) / step
                a11 += d1 * d1
                a12 += d1 * d2
                a22 += d2 * d2
                g1 += d1 * r[c]
                g2 += d2 * r[c]
            a11 += 1e-12
            a22 += 1e-12
            det = a11 * a22 - a12 * a12
            delta1 = (a22 * g1 - a12 * g2) / det
            delta2 = (a11 * g2 - a12 * g1) / det
            scale = 1.0
            better = False
            for _ in range(halvings):
                t1 = min(max(b1 - scale * delta1, -0.5), 1.5)
                t2 = min(max(b2 - scale * delta2, -0.5), 1.5)
                _residual(vn, tri, f, t1, t2, emitter, receiver, r1)
                if _size(r1) <= size:
                    b1, b2 = t1, t2
                    r[0], r[1], r[2] = r1[0], r1[1], r1[2]
                    better = True
                    break
                scale /= 2
            if not better:  # stuck
                break
        _residual(vn, tri, f, b1, b2, emitter, receiver, r)
        b_out[i, 0], b_out[i, 1] = b1, b2
        ok[i] = _size(r) < converged and min(1 - (b1 + b2), min(b1, b2)) >= -inside
    return ok
