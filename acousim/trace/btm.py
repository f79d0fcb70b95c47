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
applied by the caller as a factor.  Second order (edge to edge, two edges sharing a
plane): :func:`edge_pair_elements`, the double line integral, discretised on its
own (equal elements, bins of path length).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "EdgeElements",
    "EdgePairElements",
    "Wedge",
    "edge_pair_elements",
    "many_edge_elements",
    "edge_elements",
    "DEFAULT_STEP_M",
    "DEFAULT_MAX_EXCESS_M",
]

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
    into face 1; normal (3,): face 1's unit normal, towards the air; wedge_rad: open
    (air) angle of the wedge, in (pi, 2 pi]; source, receiver (3,); step_m: excess
    path length per element (m); elements whose path is longer than max_path_m are
    left out; reflection: pressure reflection factors (R1, R2) of face 1 and face 2,
    which scale the two terms tied to the images in those faces (phi_4 and phi_1:
    the ones that make the reflection boundaries continuous); 1 for a rigid wedge;
    max_excess_m: the response is kept up to this excess path length beyond the
    apex, its second half tapered (the far parts of a long edge add little in the
    band but cost one element per step).
    """
    el, _ = many_edge_elements(
        np.asarray(start, float)[None],
        np.asarray(end, float)[None],
        np.asarray(face_dir, float)[None],
        np.asarray(normal, float)[None],
        np.array([wedge_rad], float),
        np.asarray(source, float),
        np.asarray(receiver, float),
        step_m,
        max_path_m,
        np.array([reflection], float),
        max_excess_m,
    )
    return el


def many_edge_elements(
    start: np.ndarray,
    end: np.ndarray,
    face_dir: np.ndarray,
    normal: np.ndarray,
    wedge_rad: np.ndarray,
    source: np.ndarray,
    receiver: np.ndarray,
    step_m: float = DEFAULT_STEP_M,
    max_path_m: float = np.inf,
    reflection: np.ndarray | None = None,
    max_excess_m: float = DEFAULT_MAX_EXCESS_M,
    terms: np.ndarray | None = None,
) -> tuple[EdgeElements, np.ndarray]:
    """:func:`edge_elements` of E edges at once (arrays (E, 3) and (E,); reflection
    (E, 2)); one receiver (3,) and one source (3,) or one per edge (E, 3).  Returns
    the elements of all edges and the edge index (K,) of each.  `terms` (E, 4), if
    given, weighs the four terms of each edge in place of ``(R2, 1, 1, R1)`` (a part
    of the response alone: the image term of one face, say)."""
    n_e = wedge_rad.size
    source, receiver = np.asarray(source, float), np.asarray(receiver, float)
    if reflection is None:
        reflection = np.ones((n_e, 2))
    length = np.linalg.norm(end - start, axis=1)
    good = length > 0
    axis = (end - start) / np.where(good, length, 1.0)[:, None]

    def cyl(p):
        d = p - start
        z = np.einsum("ij,ij->i", d, axis)
        v = d - z[:, None] * axis
        th = np.arctan2(np.einsum("ij,ij->i", v, normal), np.einsum("ij,ij->i", v, face_dir))
        return np.linalg.norm(v, axis=1), np.mod(th, 2 * np.pi), z

    rS, tS, zS = cyl(source)
    rR, tR, zR = cyl(receiver)
    tiny = 1e-9 * np.maximum(np.maximum(rS, rR), length)
    # on the edge line or inside the solid: nothing
    good &= (rS > tiny) & (rR > tiny) & (tS <= wedge_rad) & (tR <= wedge_rad) & (step_m > 0)
    rS, rR = np.where(good, rS, 1.0), np.where(good, rR, 1.0)
    nu = np.pi / wedge_rad

    def path(z, i):
        return np.hypot(rS[i], z - zS[i]) + np.hypot(rR[i], z - zR[i])

    every = np.arange(n_e)
    # 1. the apex, clipped to the edge
    z_mid = (rR * zS + rS * zR) / (rS + rR)  # unclipped
    z_apex = np.clip(z_mid, 0.0, length)
    l_apex = path(z_apex, every)
    # 2. element boundaries in excess path length on each side (side 0: towards z = 0)
    side_edge = np.repeat(every, 2)
    z_end = np.column_stack([np.zeros(n_e), length]).ravel()
    real_end = path(z_end, side_edge) - l_apex[side_edge]
    cut = real_end > max_excess_m  # an artificial end: taper towards it
    e_end = np.minimum(np.minimum(real_end, max_path_m - l_apex[side_edge]), max_excess_m)
    live = good[side_edge] & (np.abs(z_end - z_apex[side_edge]) > 0) & (e_end > 0)
    e_cap = float(e_end[live].max()) if live.any() else 0.0
    template = np.concatenate(
        [
            [0.0],
            step_m * 0.5 ** np.arange(_REFINE, 0, -1),
            step_m * np.arange(1, int(np.ceil(e_cap / step_m)) + 1),
        ]
    )
    n_inner = np.where(live, np.searchsorted(template, e_end, side="left"), 0)  # entries < end
    sides = np.flatnonzero(live & (n_inner > 0))
    if sides.size == 0:
        return EdgeElements.empty(), np.zeros(0, int)
    counts = n_inner[sides]  # elements per side
    side_of = np.repeat(sides, counts)  # per element
    offset = np.cumsum(counts) - counts
    j = np.arange(side_of.size) - np.repeat(offset, counts)  # element index within its side
    ea_ex = template[j]
    eb_ex = np.where(
        j + 1 < np.repeat(counts, counts),
        template[np.minimum(j + 1, template.size - 1)],
        e_end[side_of],
    )
    mid_ex = 0.5 * (ea_ex + eb_ex)
    edge_of = side_edge[side_of]
    upper = (side_of % 2) == 1
    src = np.broadcast_to(source, (n_e, 3))[edge_of]
    za, zb, zc = _on_spheroid_many(
        src,
        receiver,
        start[edge_of],
        axis[edge_of],
        l_apex[edge_of] + np.stack([ea_ex, eb_ex, mid_ex]),
        upper,
    )
    lo = np.minimum(z_apex[edge_of], z_end[side_of])
    hi = np.maximum(z_apex[edge_of], z_end[side_of])
    za, zb, zc = np.clip(za, lo, hi), np.clip(zb, lo, hi), np.clip(zc, lo, hi)
    za = np.where(j == 0, z_apex[edge_of], za)  # exactly (roots lose precision at the apex)
    x = np.clip((mid_ex - max_excess_m / 2) / (max_excess_m / 2), 0, 1)
    taper = np.where(cut[side_of], 0.5 * (1 + np.cos(np.pi * x)), 1.0)
    # 3. product integration in eta
    g = edge_of
    phi = np.pi + np.stack([tS + tR, tS - tR, -tS + tR, -tS - tR], axis=1)  # (E, 4)
    half = nu[:, None] * phi / 2
    s, c = np.sin(half), np.cos(half)
    flip = s < 0
    s, c = np.where(flip, -s, s), np.where(flip, -c, c)
    weight4 = (
        np.column_stack([reflection[:, 1], np.ones(n_e), np.ones(n_e), reflection[:, 0]])
        if terms is None
        else np.asarray(terms, float)
    )

    # per-element copies of the per-edge values, gathered once
    rS_g, rR_g, zS_g, zR_g, nu_g = rS[g], rR[g], zS[g], zR[g], nu[g]

    def eta(z):
        # cosh(eta) - 1 without cancellation:
        # ((rS + rR)(z - z_mid))^2 / ((m l - (z - zS)(z - zR) + rS rR) rS rR)
        a, b = z - zS_g, z - zR_g
        ml = np.hypot(rS_g, a) * np.hypot(rR_g, b)
        arg = ((rS_g + rR_g) * (z - z_mid[g])) ** 2 / ((ml - a * b + rS_g * rR_g) * rS_g * rR_g)
        return _acosh1p(arg)

    ea, eb = eta(np.stack([za, zb]))
    ea = np.where(j == 0, np.where(z_apex[g] == z_mid[g], 0.0, ea), ea)

    def prim(e):  # weighted sum over the four terms of atan(tanh(nu eta/2) / tan(nu phi/2))
        t = np.tanh(nu_g * e / 2)[..., None]
        return (np.arctan2(t * c[g], s[g]) * weight4[g]).sum(axis=-1)

    # eta grows away from the apex on both sides: each element runs from ea to eb
    pb, pa = prim(np.stack([eb, ea]))
    integral = (2 / nu_g) * (pb - pa)
    deta = np.abs(eb - ea)
    m_c = np.hypot(rS_g, zc - zS_g)
    l_c = np.hypot(rR_g, zc - zR_g)
    ok = deta > 0
    weight = np.where(ok, np.abs(zb - za) / np.where(ok, deta, 1.0), 0.0) / (m_c * l_c)
    amp = -(nu_g / (4 * np.pi)) * weight * integral * taper
    # 4. one impulse per element at its mid-path point
    keep = ok & (amp != 0)
    pts_c = start[g[keep]] + zc[keep, None] * axis[g[keep]]
    return EdgeElements(pts_c, m_c[keep], l_c[keep], amp[keep]), g[keep]


def _on_spheroid_many(source, receiver, start, axis, path_m, upper):
    """Positions z along K lines start + z axis (start, axis (K, 3)) where
    |S - x| + |x - R| = path_m (K,): points of equal path length lie on a spheroid
    with foci S and R (semi-axes a = path / 2, b = sqrt(a^2 - |S - R|^2 / 4)), whose
    intersection with a line is a quadratic in z; upper (K,): the larger root (else
    the smaller).  source, receiver: (3,) or (K, 3); path_m may be (..., K): several
    path lengths per line, solved at once."""
    k = np.shape(path_m)[-1]
    source = np.broadcast_to(source, (k, 3))
    receiver = np.broadcast_to(receiver, (k, 3))
    centre = 0.5 * (source + receiver)
    focal = receiver - source
    c = 0.5 * np.linalg.norm(focal, axis=1)
    # unit focal axis (zero for a sphere, S = R: then any axis will do)
    u = focal / np.where(c > 0, 2 * c, 1.0)[:, None]
    a2 = (0.5 * path_m) ** 2
    b2 = np.maximum(a2 - c * c, 0.0)
    y0 = start - centre
    y0u = np.einsum("ij,ij->i", y0, u)
    eu = np.einsum("ij,ij->i", axis, u)
    y0e = np.einsum("ij,ij->i", y0, axis)
    q2 = b2 * eu**2 + a2 * (1 - eu**2)
    q1 = 2 * (b2 * y0u * eu + a2 * (y0e - y0u * eu))
    q0 = b2 * y0u**2 + a2 * (np.einsum("ij,ij->i", y0, y0) - y0u**2) - a2 * b2
    root = np.sqrt(np.maximum(q1**2 - 4 * q2 * q0, 0.0))
    return (-q1 + np.where(upper, root, -root)) / (2 * q2)


def _acosh1p(x: np.ndarray) -> np.ndarray:
    """acosh(1 + x), accurate for small x >= 0."""
    x = np.maximum(x, 0.0)
    return np.log1p(x + np.sqrt(x * (x + 2)))


# -- second order: edge to edge ---------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Wedge:
    """One straight wedge as the second-order integral needs it (world frame, metres).

    start_m, end_m (3,): edge endpoints; face_dir (3,): unit direction from the edge
    into face 1; normal (3,): face 1's unit normal, towards the air; angle_rad: open
    (air) angle in (pi, 2 pi]; reflection: pressure reflection factors (R1, R2) of
    face 1 and face 2 (1: rigid); terms: the weights of the four beta terms in the
    order of :meth:`beta` (None: ``(R2, 1, 1, R1)``; a part of the wedge's response,
    e.g. the image term of one face alone, as :func:`many_edge_elements` takes).
    """

    start_m: np.ndarray
    end_m: np.ndarray
    face_dir: np.ndarray
    normal: np.ndarray
    angle_rad: float
    reflection: tuple[float, float] = (1.0, 1.0)
    terms: tuple[float, float, float, float] | None = None

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.end_m - self.start_m))

    @property
    def axis(self) -> np.ndarray:
        return (self.end_m - self.start_m) / self.length_m

    def cylindrical(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(r, theta, z) of points p (..., 3) about the edge; theta in [0, 2 pi) from
        face 1 towards its normal, z along the edge from its start."""
        d = np.asarray(p, float) - self.start_m
        z = d @ self.axis
        v = d - z[..., None] * self.axis
        th = np.mod(np.arctan2(v @ self.normal, v @ self.face_dir), 2 * np.pi)
        return np.linalg.norm(v, axis=-1), th, z

    def beta(self, th_a, th_b, cosh_eta) -> np.ndarray:
        """Sum of the four beta terms for angles th_a, th_b (of the two ends about
        the edge) and cosh(eta); the terms of the images in face 1 and face 2 are
        scaled by their reflection factors (as in :func:`many_edge_elements`)."""
        nu = np.pi / self.angle_rad
        c = np.cosh(nu * np.arccosh(np.maximum(cosh_eta, 1.0)))
        r1, r2 = self.reflection
        weights = (r2, 1.0, 1.0, r1) if self.terms is None else self.terms
        out = 0.0
        for w, phi in zip(
            weights,
            (
                np.pi + th_a + th_b,
                np.pi + th_a - th_b,
                np.pi - th_a + th_b,
                np.pi - th_a - th_b,
            ),
        ):
            if w != 0:
                out = out + w * np.sin(nu * phi) / (c - np.cos(nu * phi))
        return out


@dataclass(frozen=True, eq=False)
class EdgePairElements:
    """K elements of the edge-to-edge paths S -> edge 1 -> edge 2 -> R (world frame).

    first_point_m (K, 3): mean point on edge 1; point_m (K, 3): mean point on edge 2;
    first_leg_m (K,): path length from S over edge 1 to point_m; second_leg_m (K,):
    |point_m - R|; amplitude (K,): the element's impulse amplitude at R (free field
    ``1/r`` units), signed.  The path length of an element at R is exact
    (first_leg_m + second_leg_m); its points are means over the element.
    """

    first_point_m: np.ndarray
    point_m: np.ndarray
    first_leg_m: np.ndarray
    second_leg_m: np.ndarray
    amplitude: np.ndarray

    def __len__(self) -> int:
        return self.amplitude.size

    @staticmethod
    def empty() -> EdgePairElements:
        z3, z = np.zeros((0, 3)), np.zeros(0)
        return EdgePairElements(z3, z3, z, z, z)


#: pairs of edge elements evaluated at once (memory: about 30 arrays of this size)
_PAIR_CHUNK = 1 << 19


def edge_pair_elements(
    wedge1: Wedge,
    wedge2: Wedge,
    theta_12: float,
    theta_21: float,
    sides: int,
    source: np.ndarray,
    receiver: np.ndarray,
    step_m: float = DEFAULT_STEP_M,
    max_path_m: float = np.inf,
    max_excess_m: float = DEFAULT_MAX_EXCESS_M,
) -> EdgePairElements:
    """Second-order (edge-to-edge) BTM diffraction of two edges that share a face.

    The double line integral (the edge-source form of Svensson and Calamia)::

        h_2(t) = f (nu1 nu2 / 16 pi^2) int int delta(t - (m + n + l)/c)
                 beta_1 beta_2 / (m n l) dz1 dz2

    with m = |S - z1|, n = |z1 - z2|, l = |z2 - R|; beta_1 the first-order beta sum
    of wedge 1 for the source S and the "receiver" z2 (at angle theta_12 about edge
    1: 0 or the open angle, as edge 2 lies on a face plane of wedge 1), beta_2 that of
    wedge 2 for the "source" z1 (angle theta_21) and R.  The path from z1 to z2 runs
    along the shared face, where the field of edge 1 already holds the face's
    doubling and an edge source of edge 2 on its own face is doubled again: each side
    of the face along which the path runs counts half, ``f = sides / 2`` (1 for a box
    face, air on one side; 2 for the two rims of a thin plate, air on both sides,
    whose two products are equal because beta changes sign from one side to the
    other).  The formula is symmetric in S and R (reciprocal).

    Steps:

    1. Cut each edge into equal elements of length step_m / 2 (so that the path
       changes by at most step_m over one pair).
    2. Keep the elements that can lie on a path within ``max_excess_m`` of the
       shortest one (lower bound of the path through z1: m + |z1 - R|; through z2:
       |S - z2| + l), and for each z1 the interval of z2 whose paths can (the path
       is convex in z2: found on every 16th element, the limit relaxed by what 8
       elements can change).
    3. Evaluate the integrand at the midpoints of every kept pair (midpoint rule;
       the integrand has no singularity unless S or R lies in the plane of the
       shared face); taper the second half of the excess range (raised cosine) if
       the edges reach beyond it, as in first order.
    4. Sum the pairs into bins of step_m / 4 of path length (a phase spread of
       +-0.18 rad at 85 kHz): one element per bin, at the bin's mean path length
       (weights |amplitude|) and mean points.

    wedge1, wedge2: the two wedges, oriented for S and for R (the air around each is
    at angles 0 .. angle_rad); source, receiver (3,); step_m: path length per bin
    (m); pairs longer than max_path_m are left out; theta_12, theta_21: the angle
    of edge 2 about edge 1 and of edge 1 about edge 2 (rad); sides: 1 or 2 (above).
    """
    source, receiver = np.asarray(source, float), np.asarray(receiver, float)
    if sides <= 0 or step_m <= 0:
        return EdgePairElements.empty()
    # 1. elements
    pts, dzs = [], []
    for w in (wedge1, wedge2):
        n = max(int(np.ceil(w.length_m / (step_m / 2))), 1)
        t = (np.arange(n) + 0.5) / n
        pts.append(w.start_m + t[:, None] * (w.end_m - w.start_m))
        dzs.append(w.length_m / n)
    p1, p2 = pts
    m_all = np.linalg.norm(p1 - source, axis=1)
    l_all = np.linalg.norm(p2 - receiver, axis=1)
    # 2. an upper bound of the shortest path (a coarse grid), lower bounds per element
    c1 = np.unique(np.linspace(0, len(p1) - 1, min(len(p1), 65)).astype(int))
    c2 = np.unique(np.linspace(0, len(p2) - 1, min(len(p2), 65)).astype(int))
    n_c = np.linalg.norm(p1[c1, None, :] - p2[None, c2, :], axis=2)
    shortest = float((m_all[c1, None] + n_c + l_all[None, c2]).min())
    limit = min(shortest + max_excess_m, max_path_m)
    k1 = np.flatnonzero(m_all + np.linalg.norm(p1 - receiver, axis=1) <= limit)
    k2 = np.flatnonzero(np.linalg.norm(p2 - source, axis=1) + l_all <= limit)
    if k1.size == 0 or k2.size == 0:
        return EdgePairElements.empty()
    # does the domain reach beyond max_excess (then taper): path is convex in (z1, z2)
    ends1 = np.stack([wedge1.start_m, wedge1.end_m])
    ends2 = np.stack([wedge2.start_m, wedge2.end_m])
    far = (
        np.linalg.norm(ends1 - source, axis=1)[:, None]
        + np.linalg.norm(ends1[:, None] - ends2[None], axis=2)
        + np.linalg.norm(ends2 - receiver, axis=1)[None, :]
    ).max()
    cut = far - shortest > max_excess_m
    rS, tS, zS = wedge1.cylindrical(source)
    rR, tR, zR = wedge2.cylindrical(receiver)
    nu1, nu2 = np.pi / wedge1.angle_rad, np.pi / wedge2.angle_rad
    scale = 0.5 * sides * nu1 * nu2 / (16 * np.pi**2) * dzs[0] * dzs[1]
    z1_on1 = (p1 - wedge1.start_m) @ wedge1.axis
    z2_on2 = (p2 - wedge2.start_m) @ wedge2.axis
    r2_1, _, z2_1 = wedge1.cylindrical(p2)  # edge 2's elements about edge 1
    r1_2, _, z1_2 = wedge2.cylindrical(p1)  # edge 1's elements about edge 2
    # the pairs within the limit: for each z1 an interval of z2 (the path is convex
    # in z2), found on every G-th z2 with the limit relaxed by what G / 2 elements
    # can change (the path changes by at most 2 dz2 per element)
    g_step = 16
    coarse = k2[::g_step]
    coarse = np.unique(np.append(coarse, k2[-1]))
    n_c = np.linalg.norm(p1[k1, None, :] - p2[None, coarse, :], axis=2)
    near = m_all[k1, None] + n_c + l_all[None, coarse] <= limit + g_step * dzs[1]
    any_ = near.any(axis=1)
    first_c = np.argmax(near, axis=1)
    last_c = near.shape[1] - 1 - np.argmax(near[:, ::-1], axis=1)
    lo = np.clip(coarse[first_c] - g_step, k2[0], k2[-1] + 1)
    hi = np.clip(coarse[last_c] + g_step + 1, k2[0], k2[-1] + 1)
    rows, lo, hi = k1[any_], lo[any_], hi[any_]
    counts = np.maximum(hi - lo, 0)
    parts = []
    start = 0
    while start < rows.size:
        # as many rows as fit in one chunk of pairs (at least one)
        stop = start + max(1, int(np.searchsorted(np.cumsum(counts[start:]), _PAIR_CHUNK)))
        c = counts[start:stop]
        a = np.repeat(rows[start:stop], c)
        b = np.repeat(lo[start:stop], c) + (np.arange(c.sum()) - np.repeat(np.cumsum(c) - c, c))
        start = stop
        if a.size == 0:
            continue
        n = np.linalg.norm(p1[a] - p2[b], axis=1)
        path = m_all[a] + n + l_all[b]
        ok = (path <= limit) & (r2_1[b] > 0) & (r1_2[a] > 0)
        a, b = a[ok], b[ok]
        if a.size == 0:
            continue
        m, n, l_, path = m_all[a], n[ok], l_all[b], path[ok]
        # 3. the integrand at the midpoints
        cosh1 = ((z1_on1[a] - zS) * (z1_on1[a] - z2_1[b]) + m * n) / (rS * r2_1[b])
        cosh2 = ((z2_on2[b] - z1_2[a]) * (z2_on2[b] - zR) + n * l_) / (r1_2[a] * rR)
        with np.errstate(divide="ignore", invalid="ignore"):
            amp = (
                scale
                * wedge1.beta(tS, theta_12, cosh1)
                * wedge2.beta(theta_21, tR, cosh2)
                / (m * n * l_)
            )
        if cut:
            x = np.clip((path - shortest - max_excess_m / 2) / (max_excess_m / 2), 0, 1)
            amp = amp * 0.5 * (1 + np.cos(np.pi * x))
        good = np.isfinite(amp) & (amp != 0)
        parts.append((a[good], b[good], path[good], amp[good]))
    if not parts:
        return EdgePairElements.empty()
    a, b, path, amp = (np.concatenate(x) for x in zip(*parts))
    if a.size == 0:
        return EdgePairElements.empty()
    # 4. bins of step_m / 4 in path length
    bin_ = np.floor((path - path.min()) / (step_m / 4)).astype(int)
    used = np.flatnonzero(np.bincount(bin_))
    w = np.abs(amp)
    wsum = np.bincount(bin_, w)[used]
    wsum = np.where(wsum > 0, wsum, 1.0)

    def mean(x):
        return np.bincount(bin_, w * x)[used] / wsum

    total = np.bincount(bin_, amp)[used]
    length = mean(path)
    q1 = np.column_stack([mean(p1[a, i]) for i in range(3)])
    q2 = np.column_stack([mean(p2[b, i]) for i in range(3)])
    second = np.linalg.norm(q2 - receiver, axis=1)
    return EdgePairElements(q1, q2, length - second, second, total)
