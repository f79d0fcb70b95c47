"""Edge diffraction by a rigid wedge: the Biot-Tolstoy-Medwin (BTM) edge-source model.

The exact impulse response of an infinite rigid wedge lit by a point source whose
free field is ``delta(t - r/c) / r`` is the geometric part plus a diffracted part
that is an integral along the edge (Biot & Tolstoy 1957, Medwin 1981; the line
integral form of Svensson, Fred & Vanderkooy, JASA 106(5), 1999)::

    h_d(t) = -(nu / 4 pi) * sum_{i=1..4} integral delta(t - (m + l)/c) beta_i / (m l) dz

    beta_i = sin(nu phi_i) / (cosh(nu eta) - cos(nu phi_i))
    phi_1..4 = pi + thS + thR, pi + thS - thR, pi - thS + thR, pi - thS - thR
    cosh(eta) = ((z - zS)(z - zR) + m l) / (rS rR)

with ``nu = pi / thW`` (``thW`` the open angle of air around the edge: 2 pi for a thin
screen, 3 pi / 2 for a box edge), ``m = |S - z|``, ``l = |z - R|``, and (r, th, z) the
cylindrical coordinates of the source S and the receiver R about the edge, ``th``
measured through the air from face 1.  For a finite edge the integral runs over the
edge only (which is what the edge-source model prescribes for finite wedges).

Discretisation (this module; a pure function of the geometry):

1. Split the edge at its apex point (the point of least path length m + l).
2. On each side, cut the edge at equal steps ``step_m`` of excess path length
   ``m + l - L_apex`` (so each element spans about ``step_m / c`` of delay; the first
   step is subdivided geometrically, 8 times, where the integrand peaks), up to the
   edge's end or ``max_excess_m``, whichever comes first; in the latter case the
   second half of the kept response is tapered (raised cosine), so that the cut
   adds no spurious end echo.
3. Integrate each element by product integration in the variable eta: the peaked
   factor ``beta_i`` is integrated exactly,
   ``integral beta_i d eta = (2 / nu) atan(tanh(nu eta / 2) / tan(nu phi_i / 2))``,
   and the smooth weight ``(dz / d eta) / (m l)`` is taken at the element.  Near a
   shadow or reflection boundary beta_i tends to a delta function at the apex whose
   weight jumps sign across the boundary; the closed form integrates it exactly (the
   analytic treatment of the apex element of Svensson & Calamia), so that geometric
   plus diffracted field is continuous across the boundary.
4. Each element becomes one impulse at its mid-path point: in the tracer's path
   form a point reflector with anchor = the element's point on the edge,
   first leg = m, and strength = amplitude * l (its gain at the receiver is the
   amplitude).

Valid for rigid (or uniformly reflecting) straight edges; the faces' absorption is
applied by the caller as a factor.  Not modelled here: edge-to-edge (second-order)
diffraction, which the stage adds by combining these elements.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["EdgeElements", "edge_elements", "cylindrical", "DEFAULT_STEP_M", "DEFAULT_MAX_EXCESS_M"]

#: default excess path length per edge element (m): a quarter wavelength at 85 kHz
DEFAULT_STEP_M = 1e-3
#: default length of the edge's response kept, in excess path length (m); its last
#: half is tapered (raised cosine) so that the cut makes no spurious end echo
DEFAULT_MAX_EXCESS_M = 0.05
#: the first steps next to the apex are subdivided by halving this many times
_REFINE = 8


@dataclass(frozen=True, eq=False)
class EdgeElements:
    """K edge elements of one edge for one source-receiver pair (world frame, metres).

    point_m (K, 3): the element's point on the edge (its mid-path point);
    first_leg_m (K,): |S - point|; second_leg_m (K,): |point - R|;
    amplitude (K,): the element's impulse amplitude at R (free field ``1/r`` units),
    signed.
    """

    point_m: np.ndarray
    first_leg_m: np.ndarray
    second_leg_m: np.ndarray
    amplitude: np.ndarray

    def __len__(self) -> int:
        return self.amplitude.size

    @staticmethod
    def empty() -> EdgeElements:
        z = np.zeros(0)
        return EdgeElements(np.zeros((0, 3)), z, z, z)


def cylindrical(
    points: np.ndarray,
    start: np.ndarray,
    axis: np.ndarray,
    face_dir: np.ndarray,
    normal: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cylindrical coordinates (r, theta, z) of points (N, 3) about an edge.

    `axis` is the unit edge direction from `start`, `face_dir` the unit direction
    from the edge into face 1 (perpendicular to the edge), `normal` face 1's outward
    normal (towards the air).  theta in [0, 2 pi) is measured from face 1 through
    the air.
    """
    d = np.atleast_2d(points) - start
    z = d @ axis
    v = d - z[:, None] * axis
    r = np.linalg.norm(v, axis=1)
    theta = np.mod(np.arctan2(v @ normal, v @ face_dir), 2 * np.pi)
    return r, theta, z


def edge_elements(
    start: np.ndarray,
    end: np.ndarray,
    face_dir: np.ndarray,
    normal: np.ndarray,
    wedge_rad: float,
    source: np.ndarray,
    receiver: np.ndarray,
    step_m: float = DEFAULT_STEP_M,
    max_path_m: float = np.inf,
    reflection: tuple[float, float] = (1.0, 1.0),
    max_excess_m: float = DEFAULT_MAX_EXCESS_M,
) -> EdgeElements:
    """BTM edge elements of one straight rigid edge (see the module docstring).

    start, end (3,): edge endpoints; face_dir (3,): unit direction from the edge
    into face 1; normal (3,): face 1's outward unit normal; wedge_rad: open (air)
    angle of the wedge, in (pi, 2 pi]; source, receiver (3,); step_m: excess path
    length per element (m); elements whose path is longer than max_path_m are left
    out.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = float(np.linalg.norm(end - start))
    if length <= 0 or step_m <= 0:
        return EdgeElements.empty()
    axis = (end - start) / length
    pts = np.stack([np.asarray(source, float), np.asarray(receiver, float)])
    (rS, rR), (tS, tR), (zS, zR) = cylindrical(pts, start, axis, face_dir, normal)
    tiny = 1e-9 * max(rS, rR, length)
    if rS <= tiny or rR <= tiny or tS > wedge_rad or tR > wedge_rad:
        return EdgeElements.empty()  # on the edge line or inside the solid
    nu = np.pi / wedge_rad

    def path(z):
        return np.hypot(rS, z - zS) + np.hypot(rR, z - zR)

    pts = pts.astype(float)

    # 1. the apex, clipped to the edge
    z_apex = float(np.clip((rR * zS + rS * zR) / (rS + rR), 0.0, length))
    l_apex = path(z_apex)
    # 2. element boundaries (and mid points) in excess path length on each side
    bounds = []
    for z_end in (0.0, length):
        excess_end = path(z_end) - l_apex
        if abs(z_end - z_apex) <= 0 or excess_end <= 0:
            continue
        cut = excess_end > max_excess_m  # an artificial end: taper towards it
        excess_end = min(excess_end, max_path_m - l_apex, max_excess_m)
        if excess_end <= 0:
            continue
        first = step_m * 0.5 ** np.arange(_REFINE, 0, -1)
        rest = step_m * np.arange(1, int(np.ceil(excess_end / step_m)) + 1)
        e = np.concatenate([[0.0], first[first < excess_end], rest[rest < excess_end]])
        e = np.append(e, excess_end)
        mid = 0.5 * (e[:-1] + e[1:])
        z = _on_spheroid(
            pts[0], pts[1], start, axis, l_apex + np.concatenate([e, mid]), z_end > z_apex
        )
        z = np.clip(z, min(z_apex, z_end), max(z_apex, z_end))
        z[0] = z_apex  # exactly (the roots lose precision where the path is flat)
        taper = np.ones(mid.size)
        if cut:
            x = np.clip((mid - max_excess_m / 2) / (max_excess_m / 2), 0, 1)
            taper = 0.5 * (1 + np.cos(np.pi * x))
        bounds.append((z[: e.size], z[e.size :], taper))
    if not bounds:
        return EdgeElements.empty()
    za = np.concatenate([b[0][:-1] for b in bounds])
    zb = np.concatenate([b[0][1:] for b in bounds])
    zc = np.concatenate([b[1] for b in bounds])
    taper = np.concatenate([b[2] for b in bounds])
    # 3. product integration in eta
    phi = np.pi + np.array([tS + tR, tS - tR, -tS + tR, -tS - tR])
    half = nu * phi / 2
    s, c = np.sin(half), np.cos(half)
    flip = s < 0
    term_weight = np.array([reflection[1], 1.0, 1.0, reflection[0]], float)
    s, c = np.where(flip, -s, s), np.where(flip, -c, c)

    z_mid = (rR * zS + rS * zR) / (rS + rR)  # the unclipped apex

    def eta(z):
        # cosh(eta) - 1 rewritten without cancellation:
        # ((rS + rR)(z - z_mid))^2 / ((m l - (z - zS)(z - zR) + rS rR) rS rR)
        a, b = z - zS, z - zR
        ml = np.hypot(rS, a) * np.hypot(rR, b)
        arg = ((rS + rR) * (z - z_mid)) ** 2 / ((ml - a * b + rS * rR) * rS * rR)
        return _acosh1p(arg)

    ea, eb = eta(za), eta(zb)

    def prim(e):  # weighted sum over the four terms of atan(tanh(nu eta/2) / tan(nu phi/2))
        t = np.tanh(nu * e / 2)[:, None]
        return np.arctan2(t * c[None, :], s[None, :]) @ term_weight

    # eta grows away from the apex on both sides: each element runs from ea to eb
    integral = (2 / nu) * (prim(eb) - prim(ea))
    deta = np.abs(eb - ea)
    m_c = np.hypot(rS, zc - zS)
    l_c = np.hypot(rR, zc - zR)
    dz = np.abs(zb - za)
    ok = deta > 0
    weight = np.where(ok, dz / np.where(ok, deta, 1.0), 0.0) / (m_c * l_c)
    amp = -(nu / (4 * np.pi)) * weight * integral * taper
    # 4. one impulse per element at its mid-path point
    keep = ok & (amp != 0)
    pts_c = start + zc[keep, None] * axis
    return EdgeElements(pts_c, m_c[keep], l_c[keep], amp[keep])


def _acosh1p(x: np.ndarray) -> np.ndarray:
    """acosh(1 + x), accurate for small x >= 0."""
    x = np.maximum(x, 0.0)
    return np.log1p(x + np.sqrt(x * (x + 2)))


def _on_spheroid(
    source: np.ndarray,
    receiver: np.ndarray,
    start: np.ndarray,
    axis: np.ndarray,
    path_m: np.ndarray,
    upper: bool,
) -> np.ndarray:
    """Positions z along the line start + z axis where |S - x| + |x - R| = path_m.

    Points of equal path length lie on a spheroid with foci S and R (semi-axes
    a = path / 2 and b = sqrt(a^2 - |S - R|^2 / 4)); its intersection with the line
    is a quadratic in z.  upper: the larger root (else the smaller).
    """
    centre = 0.5 * (source + receiver)
    focal = receiver - source
    c = 0.5 * np.linalg.norm(focal)
    u = focal / (2 * c) if c > 0 else axis
    a2 = (0.5 * path_m) ** 2
    b2 = np.maximum(a2 - c * c, 0.0)
    y0 = start - centre
    y0u, eu, y0e = y0 @ u, axis @ u, y0 @ axis
    q2 = b2 * eu**2 + a2 * (1 - eu**2)
    q1 = 2 * (b2 * y0u * eu + a2 * (y0e - y0u * eu))
    q0 = b2 * y0u**2 + a2 * (y0 @ y0 - y0u**2) - a2 * b2
    root = np.sqrt(np.maximum(q1**2 - 4 * q2 * q0, 0.0))
    return (-q1 + (root if upper else -root)) / (2 * q2)
