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
plane): :mod:`acousim.trace.diffraction.pairs`, whose inner integral is this one
(:func:`integrate_rows`, a source on the face of the second edge).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.scene.model import Diffraction
from processing.base.kernels import optional_kernel

__all__ = [
    "EdgeCoordinates",
    "EdgeElements",
    "EdgeRows",
    "integrate_rows",
    "many_edge_elements",
    "edge_elements",
    "DEFAULT_STEP_M",
    "ElementLimits",
    "DEFAULT_LIMITS",
    "Wedge",
    "DEFAULT_MAX_EXCESS_M",
]

#: default excess path length per edge element (m): a quarter wavelength at 85 kHz
#: the element step's default: the scene's declaration (:class:`acousim.scene.model.Diffraction`)
DEFAULT_STEP_M = Diffraction().step_m
#: default length of the edge's response kept, in excess path length (m); its last
#: half is tapered (raised cosine) so that the cut makes no spurious end echo
DEFAULT_MAX_EXCESS_M = 0.05
#: the first steps next to the apex are subdivided by halving this many times
_REFINE = 8


@dataclass(frozen=True, eq=False)
class EdgeElements:
    """K edge elements of one edge for one source-receiver pair (world frame, metres)."""

    point_m: np.ndarray
    """(K, 3) the element's point on the edge (its mid-path point), m."""
    first_leg_m: np.ndarray
    """(K,) |S - point|, m."""
    second_leg_m: np.ndarray
    """(K,) |point - R|, m."""
    amplitude: np.ndarray
    """(K,) the element's signed impulse amplitude at R (free field ``1/r`` units)."""

    def __len__(self) -> int:
        return self.amplitude.size

    @staticmethod
    def empty() -> EdgeElements:
        z = np.zeros(0)
        return EdgeElements(np.zeros((0, 3)), z, z, z)


@dataclass(frozen=True, eq=False)
class Wedge:
    """One straight wedge as the second-order integral needs it (world frame, metres).

    start_m, end_m (3,): edge endpoints; face_dir (3,): unit direction from the edge
    into face 1; normal (3,): face 1's unit normal, towards the air; angle_rad: open
    (air) angle in (pi, 2 pi]; reflection: pressure reflection factors (R1, R2) of
    face 1 and face 2 (1: rigid); terms: the weights of the four beta terms in the
    order of :meth:`beta` (None: ``(R2, 1, 1, R1)``; a part of the wedge's response,
    e.g. the image term of one face alone).  For :func:`many_edge_elements`, E wedges
    at once: every field with a leading axis of E (reflection (E, 2) or one pair for
    all, terms (E, 4) or None).
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


@dataclass(frozen=True)
class ElementLimits:
    """How an edge is cut into elements: `step_m`, the excess path length per
    element (m); elements whose path is longer than `max_path_m` are left out;
    `max_excess_m`, the response is kept up to this excess path length beyond the
    apex, its second half tapered (the far parts of a long edge add little in the
    band but cost one element per step)."""

    step_m: float = DEFAULT_STEP_M
    max_path_m: float = np.inf
    max_excess_m: float = DEFAULT_MAX_EXCESS_M


#: the default limits (the default step, no longest path, the default extent)
DEFAULT_LIMITS = ElementLimits()


def edge_elements(
    wedge: Wedge,
    source: np.ndarray,
    receiver: np.ndarray,
    limits: ElementLimits = DEFAULT_LIMITS,
) -> EdgeElements:
    """BTM edge elements of one straight edge (see the module docstring): `wedge`
    its geometry and the pressure reflection factors (R1, R2) of face 1 and face 2,
    which scale the two terms tied to the images in those faces (phi_4 and phi_1:
    the ones that make the reflection boundaries continuous; 1 for a rigid wedge);
    source, receiver (3,); `limits`: the element step, the longest path and the
    response's extent."""
    el, _ = many_edge_elements(
        Wedge(
            np.asarray(wedge.start_m, float)[None],
            np.asarray(wedge.end_m, float)[None],
            np.asarray(wedge.face_dir, float)[None],
            np.asarray(wedge.normal, float)[None],
            np.array([wedge.angle_rad], float),
            np.array([wedge.reflection], float),
            None if wedge.terms is None else np.array([wedge.terms], float),
        ),
        source,
        receiver,
        limits,
    )
    return el


@dataclass(frozen=True, eq=False)
class EdgeCoordinates:
    """E edges' unit axes (E, 3) and lengths (E,) (m), and the cylindrical
    coordinates (r, theta, z) (E,) each of a source and of a receiver about each
    edge (theta in [0, 2 pi) from face 1 towards its normal, z along the edge from
    its start), as :func:`many_edge_elements` finds them."""

    axis: np.ndarray
    length: np.ndarray
    source: tuple[np.ndarray, np.ndarray, np.ndarray]
    receiver: tuple[np.ndarray, np.ndarray, np.ndarray]

    @classmethod
    def of(cls, start, end, face_dir, normal, source, receiver) -> EdgeCoordinates:
        """Those of edges start-end (E, 3) with face 1's direction and normal (E, 3),
        for a source (3,) or (E, 3) and a receiver (3,)."""
        length = np.linalg.norm(end - start, axis=1)
        axis = (end - start) / np.where(length > 0, length, 1.0)[:, None]

        def cyl(p):
            d = p - start
            z = np.einsum("ij,ij->i", d, axis)
            v = d - z[:, None] * axis
            th = np.arctan2(np.einsum("ij,ij->i", v, normal), np.einsum("ij,ij->i", v, face_dir))
            return np.linalg.norm(v, axis=1), np.mod(th, 2 * np.pi), z

        return cls(axis, length, cyl(source), cyl(receiver))

    def take(self, keep: np.ndarray) -> EdgeCoordinates:
        """Those of the edges at `keep` (indices or a mask)."""
        return EdgeCoordinates(
            self.axis[keep],
            self.length[keep],
            tuple(x[keep] for x in self.source),
            tuple(x[keep] for x in self.receiver),
        )


def many_edge_elements(
    wedges: Wedge,
    source: np.ndarray,
    receiver: np.ndarray,
    limits: ElementLimits = DEFAULT_LIMITS,
    known: EdgeCoordinates | None = None,
) -> tuple[EdgeElements, np.ndarray]:
    """:func:`edge_elements` of E wedges at once (`wedges`' fields with a leading
    axis of E); one receiver (3,) and one source (3,) or one per edge (E, 3).
    Returns the elements of all edges and the edge index (K,) of each.  The wedges'
    `terms` (E, 4), if given, weigh the four terms of each edge in place of
    ``(R2, 1, 1, R1)`` (a part of the response alone: the image term of one face).
    known: the wedges' :class:`EdgeCoordinates` for this source and receiver, if
    already found (None: found here)."""
    start, end = np.asarray(wedges.start_m, float), np.asarray(wedges.end_m, float)
    face_dir, normal = np.asarray(wedges.face_dir, float), np.asarray(wedges.normal, float)
    wedge_rad = np.asarray(wedges.angle_rad, float)
    n_e = wedge_rad.size
    source, receiver = np.asarray(source, float), np.asarray(receiver, float)
    reflection = np.broadcast_to(np.asarray(wedges.reflection, float), (n_e, 2))
    if known is None:
        known = EdgeCoordinates.of(start, end, face_dir, normal, source, receiver)
    weight4 = (
        np.column_stack([reflection[:, 1], np.ones(n_e), np.ones(n_e), reflection[:, 0]])
        if wedges.terms is None
        else np.asarray(wedges.terms, float)
    )
    rows = EdgeRows(
        start, known.axis, known.length, wedge_rad, *known.source, *known.receiver,
        np.broadcast_to(source, (n_e, 3)), receiver, weight4,
    )  # fmt: skip
    return integrate_rows(
        rows,
        step_m=limits.step_m,
        max_path_m=np.full(n_e, limits.max_path_m),
        max_excess_m=limits.max_excess_m,
    )


@dataclass(frozen=True, eq=False)
class EdgeRows:
    """E edges, each with its own source, as the first-order integral needs them.

    start (E, 3), axis (E, 3), length (E,): the edge (m); wedge_rad (E,): open angle;
    r_s, th_s, z_s and r_r, th_r, z_r (E,): cylindrical coordinates of the source
    and the receiver about the edge (theta from face 1 through the air); source
    (E, 3), receiver (3,): the points; weight4 (E, 4): the weights of the four beta
    terms (``(R2, 1, 1, R1)`` for the whole wedge).
    """

    start: np.ndarray
    axis: np.ndarray
    length: np.ndarray
    wedge_rad: np.ndarray
    r_s: np.ndarray
    th_s: np.ndarray
    z_s: np.ndarray
    r_r: np.ndarray
    th_r: np.ndarray
    z_r: np.ndarray
    source: np.ndarray
    receiver: np.ndarray
    weight4: np.ndarray


@dataclass(frozen=True, eq=False)
class _Cuts:
    """The elements of :func:`integrate_rows` before integration (per element K)."""

    row: np.ndarray  # (K,) the row (edge) of each element
    first: np.ndarray  # (K,) True for the element next to the apex
    za: np.ndarray  # (K,) its ends and centre along the edge (m)
    zb: np.ndarray
    zc: np.ndarray
    taper: np.ndarray  # (K,) raised-cosine taper (1 where the edge is not cut)
    z_apex: np.ndarray  # (E,) the apex, clipped to the edge, and unclipped
    z_mid: np.ndarray


def integrate_rows(
    rows: EdgeRows,
    *,
    step_m: float,
    max_path_m: np.ndarray,
    max_excess_m: float,
    refine: int = _REFINE,
) -> tuple[EdgeElements, np.ndarray]:
    """The BTM elements of every row (steps 1-4 of the module docstring): the
    elements of all rows and the row of each.  max_path_m (E,): per row, elements
    whose path is longer are left out; refine: the first step is subdivided by
    halving this many times."""
    cuts = _cut(rows, step_m, max_path_m, max_excess_m, refine)
    if cuts is None:
        return EdgeElements.empty(), np.zeros(0, int)
    return _integrate(rows, cuts)


def _cut(rows: EdgeRows, step_m, max_path_m, max_excess_m, refine) -> _Cuts | None:
    """Steps 1-2: the apex and the element boundaries of every row."""
    r = rows
    n_e = r.length.size
    good = r.length > 0
    tiny = 1e-9 * np.maximum(np.maximum(r.r_s, r.r_r), r.length)
    # on the edge line or inside the solid: nothing
    good &= (r.r_s > tiny) & (r.r_r > tiny) & (r.th_s <= r.wedge_rad) & (r.th_r <= r.wedge_rad)
    good &= step_m > 0
    rS, rR = np.where(good, r.r_s, 1.0), np.where(good, r.r_r, 1.0)
    zS, zR = r.z_s, r.z_r

    def path(z, i):
        return np.hypot(rS[i], z - zS[i]) + np.hypot(rR[i], z - zR[i])

    every = np.arange(n_e)
    # 1. the apex, clipped to the edge
    z_mid = (rR * zS + rS * zR) / (rS + rR)  # unclipped
    z_apex = np.clip(z_mid, 0.0, r.length)
    l_apex = path(z_apex, every)
    # 2. element boundaries in excess path length on each side (side 0: towards z = 0)
    side_edge = np.repeat(every, 2)
    z_end = np.column_stack([np.zeros(n_e), r.length]).ravel()
    real_end = path(z_end, side_edge) - l_apex[side_edge]
    cut = real_end > max_excess_m  # an artificial end: taper towards it
    e_end = np.minimum(
        np.minimum(real_end, max_path_m[side_edge] - l_apex[side_edge]), max_excess_m
    )
    live = good[side_edge] & (np.abs(z_end - z_apex[side_edge]) > 0) & (e_end > 0)
    steps = _excess_steps(e_end, live, step_m, refine)
    if steps is None:
        return None
    side_of, j, ea_ex, eb_ex = steps
    lines = _spheroid_lines(r.source, r.receiver, r.start, r.axis)
    lo = np.minimum(z_apex[side_edge], z_end)
    hi = np.maximum(z_apex[side_edge], z_end)
    kernel = optional_kernel("acousim.trace.diffraction.element_kernel")
    if kernel is not None:  # the same numbers compiled
        sides = (side_edge, lo, hi, cut)
        out = _kernel_cuts(kernel, steps, (sides, lines, (l_apex, z_apex)), max_excess_m)
        return _Cuts(side_edge[side_of], j == 0, *out, z_apex, z_mid)
    mid_ex = 0.5 * (ea_ex + eb_ex)
    edge_of = side_edge[side_of]
    # the roots at each element's end and centre (its start is the previous
    # element's end, the same excess path, or the apex for the first), clipped to
    # the side's span
    zb, zc = _spheroid_roots(
        np.take(lines, edge_of, axis=1),
        l_apex[edge_of] + np.stack([eb_ex, mid_ex]),
        (side_of % 2) == 1,
    )
    zb, zc = np.clip(np.stack([zb, zc]), lo[side_of], hi[side_of])
    first = j == 0
    za = np.empty_like(zb)
    za[1:] = zb[:-1]
    za[first] = z_apex[edge_of[first]]  # exactly (roots lose precision at the apex)
    with np.errstate(invalid="ignore"):
        x = np.clip((mid_ex - max_excess_m / 2) / (max_excess_m / 2), 0, 1)
    taper = np.where(cut[side_of], 0.5 * (1 + np.cos(np.pi * x)), 1.0)
    return _Cuts(edge_of, first, za, zb, zc, taper, z_apex, z_mid)


def _kernel_cuts(kernel, steps, geometry, max_excess_m: float):
    """(za, zb, zc, taper) (K,) of :func:`_cut` by :mod:`.element_kernel`'s
    ``cut_points`` (steps and geometry: its arguments)."""
    out = tuple(np.empty(steps[0].size) for _ in range(4))
    kernel.cut_points(steps, *geometry, float(max_excess_m), out)
    return out


def _excess_steps(e_end: np.ndarray, live: np.ndarray, step_m: float, refine: int):
    """The elements of every live side, in excess path length: (side (K,), index
    within its side (K,), start (K,), end (K,)); steps of step_m from the apex, the
    first subdivided `refine` times by halving, the last ending at e_end (S,)."""
    e_cap = float(e_end[live].max()) if live.any() else 0.0
    template = np.concatenate(
        [
            [0.0],
            step_m * 0.5 ** np.arange(refine, 0, -1),
            step_m * np.arange(1, int(np.ceil(e_cap / step_m)) + 1),
        ]
    )
    n_inner = np.where(live, np.searchsorted(template, e_end, side="left"), 0)  # entries < end
    sides = np.flatnonzero(live & (n_inner > 0))
    if sides.size == 0:
        return None
    counts = n_inner[sides]  # elements per side
    side_of = np.repeat(sides, counts)  # per element
    offset = np.cumsum(counts) - counts
    j = np.arange(side_of.size) - np.repeat(offset, counts)  # element index within its side
    eb_ex = template[np.minimum(j + 1, template.size - 1)]
    eb_ex[offset + counts - 1] = e_end[sides]  # the last of each side ends at its end
    return side_of, j, template[j], eb_ex


def _integrate(rows: EdgeRows, cuts: _Cuts) -> tuple[EdgeElements, np.ndarray]:
    """Steps 3-4: product integration in eta, one impulse per element.  Each
    element runs from its start to its end in eta; the start of each but the
    first of its side is the end of the one before, so eta and the primitive are
    found at the ends of all (K) and at the starts of the first ones."""
    r, g, n_k = rows, cuts.row, cuts.row.size
    nu = np.pi / r.wedge_rad
    rS = np.where(r.r_s > 0, r.r_s, 1.0)
    rR = np.where(r.r_r > 0, r.r_r, 1.0)
    phi = np.pi + np.stack(
        [r.th_s + r.th_r, r.th_s - r.th_r, -r.th_s + r.th_r, -r.th_s - r.th_r], axis=1
    )  # (E, 4)
    half = nu[:, None] * phi / 2
    s, c = np.sin(half), np.cos(half)
    flip = s < 0
    s, c = np.where(flip, -s, s), np.where(flip, -c, c)
    first = np.flatnonzero(cuts.first)
    kernel = optional_kernel("acousim.trace.diffraction.element_kernel")
    if kernel is not None:
        return _integrate_compiled(kernel, rows, cuts, (nu, rS, rR, c, s), first)
    gg = np.concatenate([g, g[first]])  # every element's end, then the first starts
    # per-edge values, gathered once for the K + F points
    rS_g, rR_g, zS_g, zR_g, nu_g, zm_g, sum_g, prod_g = np.take(
        np.stack([rS, rR, r.z_s, r.z_r, nu, cuts.z_mid, rS + rR, rS * rR]), gg, axis=1
    )
    c_g, s_g, w_g = np.take(np.stack([c, s, np.asarray(r.weight4, float)]), gg, axis=1)
    z = np.concatenate([cuts.zb, cuts.za[first]])
    # cosh(eta) - 1 without cancellation:
    # ((rS + rR)(z - z_mid))^2 / ((m l - (z - zS)(z - zR) + rS rR) rS rR)
    a, b = z - zS_g, z - zR_g
    ml = np.hypot(rS_g, a) * np.hypot(rR_g, b)
    e = _acosh1p((sum_g * (z - zm_g)) ** 2 / ((ml - a * b + prod_g) * rS_g * rR_g))
    e[n_k:] = np.where(cuts.z_apex[g[first]] == cuts.z_mid[g[first]], 0.0, e[n_k:])
    # weighted sum over the four terms of atan(tanh(nu eta/2) / tan(nu phi/2))
    t = np.tanh(nu_g * e / 2)[:, None]
    prim = (np.arctan2(t * c_g, s_g) * w_g).sum(axis=-1)
    eb, pb = e[:n_k], prim[:n_k]
    ea, pa = np.empty(n_k), np.empty(n_k)
    ea[1:], pa[1:] = eb[:-1], pb[:-1]
    ea[first], pa[first] = e[n_k:], prim[n_k:]
    # eta grows away from the apex on both sides: each element runs from ea to eb
    rS_g, rR_g, zS_g, zR_g, nu_g = rS_g[:n_k], rR_g[:n_k], zS_g[:n_k], zR_g[:n_k], nu_g[:n_k]
    za, zb, zc = cuts.za, cuts.zb, cuts.zc
    integral = (2 / nu_g) * (pb - pa)
    deta = np.abs(eb - ea)
    m_c = np.hypot(rS_g, zc - zS_g)
    l_c = np.hypot(rR_g, zc - zR_g)
    ok = deta > 0
    weight = np.where(ok, np.abs(zb - za) / np.where(ok, deta, 1.0), 0.0) / (m_c * l_c)
    amp = -(nu_g / (4 * np.pi)) * weight * integral * cuts.taper
    # 4. one impulse per element at its mid-path point
    keep = np.flatnonzero(ok & (amp != 0))
    g = g[keep]
    # (np.take gathers rows much faster than indexing does)
    pts_c = np.take(r.start, g, axis=0) + zc[keep][:, None] * np.take(r.axis, g, axis=0)
    return EdgeElements(pts_c, m_c[keep], l_c[keep], amp[keep]), g


def _integrate_compiled(kernel, rows: EdgeRows, cuts: _Cuts, per_edge, first):
    """:func:`_integrate` with its arithmetic compiled (:mod:`.element_kernel`) about
    numpy's log1p, tanh and arctan2: the same elements bit for bit.  per_edge: nu,
    rS, rR, cos and sin of the half angles (E, 4) as found there; first: the indices
    of the first elements."""
    r, g, n_k = rows, cuts.row, cuts.row.size
    nu, rS, rR, c, s = per_edge
    gg = np.concatenate([g, g[first]])
    table = np.stack([rS, rR, r.z_s, r.z_r, cuts.z_mid, rS + rR, rS * rR])
    e = np.empty(gg.size)
    kernel.eta_argument(cuts.zb, cuts.za, first, g, table, e)
    e = np.log1p(e)
    e[n_k:] = np.where(cuts.z_apex[g[first]] == cuts.z_mid[g[first]], 0.0, e[n_k:])
    t = np.tanh(np.take(nu, gg) * e / 2)[:, None]
    c_g, s_g, w_g = np.take(np.stack([c, s, np.asarray(r.weight4, float)]), gg, axis=1)
    prim = (np.arctan2(t * c_g, s_g) * w_g).sum(axis=-1)
    out = (np.empty(n_k), np.empty(n_k), np.empty(n_k), np.empty((n_k, 3)), np.empty(n_k, np.intp))
    start, axis = np.ascontiguousarray(r.start, float), np.ascontiguousarray(r.axis, float)
    n = kernel.impulses(
        e,
        prim,
        (cuts.first, cuts.za, cuts.zb, cuts.zc, cuts.taper, g),
        (rS, rR, r.z_s, r.z_r, nu, start, axis),
        out,
    )
    amp, m_c, l_c, pts, edge = (x[:n] for x in out)
    return EdgeElements(pts, m_c, l_c, amp), edge


def _spheroid_lines(source, receiver, start, axis) -> np.ndarray:
    """What :func:`_spheroid_roots` needs of L lines start + z axis (start, axis (L,
    3)) and foci source, receiver ((3,) or (L, 3)): (8, L), see there."""
    n = np.shape(start)[0]
    source = np.broadcast_to(source, (n, 3))
    receiver = np.broadcast_to(receiver, (n, 3))
    centre = 0.5 * (source + receiver)
    focal = receiver - source
    c = 0.5 * np.linalg.norm(focal, axis=1)
    # unit focal axis (zero for a sphere, S = R: then any axis will do)
    u = focal / np.where(c > 0, 2 * c, 1.0)[:, None]
    y0 = start - centre
    y0u = np.einsum("ij,ij->i", y0, u)
    eu = np.einsum("ij,ij->i", axis, u)
    y0e = np.einsum("ij,ij->i", y0, axis)
    y0y0 = np.einsum("ij,ij->i", y0, y0)
    return np.stack([c * c, eu**2, 1 - eu**2, y0u, eu, y0e - y0u * eu, y0u**2, y0y0 - y0u**2])


def _spheroid_roots(lines: np.ndarray, path_m: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Positions z along K lines (`lines` (8, K): :func:`_spheroid_lines` of each)
    where |S - x| + |x - R| = path_m (..., K): points of equal path length lie on a
    spheroid with foci S and R (semi-axes a = path / 2, b = sqrt(a^2 - |S - R|^2 /
    4)), whose intersection with a line is a quadratic in z; upper (K,): the larger
    root (else the smaller)."""
    c2, eu2, one_eu2, y0u, eu, y0e_u, y0u2, y0y0_u = lines
    a2 = (0.5 * path_m) ** 2
    b2 = np.maximum(a2 - c2, 0.0)
    q2 = b2 * eu2 + a2 * one_eu2
    q1 = 2 * (b2 * y0u * eu + a2 * y0e_u)
    q0 = b2 * y0u2 + a2 * y0y0_u - a2 * b2
    root = np.sqrt(np.maximum(q1**2 - 4 * q2 * q0, 0.0))
    return (-q1 + np.where(upper, root, -root)) / (2 * q2)


def _acosh1p(x: np.ndarray) -> np.ndarray:
    """acosh(1 + x), accurate for small x >= 0."""
    x = np.maximum(x, 0.0)
    return np.log1p(x + np.sqrt(x * (x + 2)))
