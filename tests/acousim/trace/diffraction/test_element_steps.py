"""The BTM edge elements (:func:`acousim.trace.diffraction.btm.edge_elements`) are cut at equal
steps of excess path from the apex (the first step halved eight times), on both
sides of it, up to the edge's end or the extent kept: the path of every element
(its two legs) checked against the least path over the edge found by a bounded
scalar search and the step sequence written out here; and each element holds the
BTM line integral (Svensson, Fred & Vanderkooy 1999) over its own span, by
adaptive quadrature between the points where the path reaches its bounds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq, minimize_scalar

from acousim.trace.diffraction.btm import ElementLimits, Wedge, edge_elements

STEP = 1e-3
EXTENT = 0.02
REFINE = 8


def _wedge(rng) -> Wedge:
    """A box edge (open angle 3 pi / 2) of random length and direction."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    face_dir = np.cross(axis, rng.normal(size=3))
    face_dir /= np.linalg.norm(face_dir)
    normal = np.cross(axis, face_dir)
    start = rng.uniform(-0.5, 0.5, 3)
    return Wedge(start, start + rng.uniform(0.02, 0.6) * axis, face_dir, normal, 1.5 * np.pi)


def _point(rng, w: Wedge) -> np.ndarray:
    """A point in the wedge's air (theta in (0.2, 1.3 pi)), 5 to 40 cm from the edge."""
    axis = (w.end_m - w.start_m) / np.linalg.norm(w.end_m - w.start_m)
    th, r = rng.uniform(0.2, 1.3 * np.pi), rng.uniform(0.05, 0.4)
    z = rng.uniform(-0.2, 0.8) * np.linalg.norm(w.end_m - w.start_m)
    return w.start_m + z * axis + r * (np.cos(th) * w.face_dir + np.sin(th) * w.normal)


def _expected_mids(span: float) -> np.ndarray:
    """Excess path at the middle of each element of a side whose response ends at
    `span` (m) of excess path."""
    bounds = _expected_bounds(span)
    return 0.5 * (bounds[:-1] + bounds[1:])


def _expected_bounds(span: float) -> np.ndarray:
    """Excess path at the ends of the elements of a side (see _expected_mids)."""
    bounds = np.concatenate(
        [[0.0], STEP * 0.5 ** np.arange(REFINE, 0, -1), STEP * np.arange(1, span / STEP + 2)]
    )
    return np.append(bounds[bounds < span], span)


def _case(seed: int):
    """A random wedge, emitter and receiver (seeded), the edge's axis, length and path
    through a point z along it, and the least path's z and length (a bounded search,
    not the module's apex)."""
    rng = np.random.default_rng(seed)
    w = _wedge(rng)
    s, r = _point(rng, w), _point(rng, w)
    length = np.linalg.norm(w.end_m - w.start_m)
    axis = (w.end_m - w.start_m) / length

    def path(z):
        x = w.start_m + z * axis
        return np.linalg.norm(s - x) + np.linalg.norm(x - r)

    best = minimize_scalar(path, bounds=(0.0, length), method="bounded", options={"xatol": 1e-12})
    return w, s, r, (axis, length, path), (best.x, best.fun)


@pytest.mark.parametrize("seed", range(6))
def test_elements_lie_at_equal_steps_of_excess_path(seed):
    w, s, r, (axis, length, path), (z_apex, l_apex) = _case(seed)
    el = edge_elements(w, s, r, ElementLimits(step_m=STEP, max_excess_m=EXTENT))
    z = (el.point_m - w.start_m) @ axis
    # every element on the edge
    assert np.allclose(el.point_m, w.start_m + z[:, None] * axis, atol=1e-12)
    assert np.all((z >= -1e-12) & (z <= length + 1e-12))
    excess = el.first_leg_m + el.second_leg_m - l_apex
    for lower, end in ((True, 0.0), (False, length)):
        side = z < z_apex if lower else z > z_apex
        span = min(path(end) - l_apex, EXTENT)
        want = _expected_mids(span) if abs(end - z_apex) > 1e-9 else np.zeros(0)
        got = np.sort(excess[side])
        assert got.size == want.size
        # the least path is found to ~1e-12 m; the steps to rounding
        assert np.allclose(got, want, rtol=0, atol=1e-9)


def _btm_integrand(w: Wedge, s, r):
    """The BTM line integrand -(nu / 4 pi) sum_i beta_i / (m l) at z along the edge
    (Svensson, Fred & Vanderkooy 1999), from the points' own cylindrical coordinates."""
    length = np.linalg.norm(w.end_m - w.start_m)
    axis = (w.end_m - w.start_m) / length
    nu = np.pi / w.angle_rad

    def cyl(p):
        d = p - w.start_m
        z = d @ axis
        v = d - z * axis
        return (
            np.hypot(v @ w.face_dir, v @ w.normal),
            np.arctan2(v @ w.normal, v @ w.face_dir) % (2 * np.pi),
            z,
        )

    (rs, ts, zs), (rr, tr, zr) = cyl(s), cyl(r)
    phis = np.pi + np.array([ts + tr, ts - tr, -ts + tr, -ts - tr])

    def f(z):
        m, l_ = np.hypot(rs, z - zs), np.hypot(rr, z - zr)
        cosh_eta = ((z - zs) * (z - zr) + m * l_) / (rs * rr)
        c = np.cosh(nu * np.arccosh(max(cosh_eta, 1.0)))
        beta = np.sin(nu * phis) / (c - np.cos(nu * phis))
        return -(nu / (4 * np.pi)) * beta.sum() / (m * l_)

    return f


@pytest.mark.parametrize("seed", range(8))
def test_each_element_holds_the_integral_over_its_steps(seed):
    """Each element's amplitude is the BTM integral over its own span (adaptive
    quadrature between the points where the path reaches its step bounds): the
    elements tile the edge, none overlaps its neighbour or leaves a gap."""
    w, s, r, (axis, length, path), (z_apex, l_apex) = _case(100 + seed)
    el = edge_elements(w, s, r, ElementLimits(step_m=STEP, max_excess_m=1e9))
    z = (el.point_m - w.start_m) @ axis
    f = _btm_integrand(w, s, r)
    checked = 0
    for end in (0.0, length):
        if abs(end - z_apex) < 1e-6:
            continue
        side = (z < z_apex) if end == 0.0 else (z > z_apex)
        bounds = _expected_bounds(path(end) - l_apex)
        zb = (
            [z_apex]
            + [
                brentq(
                    lambda t, e=e: path(t) - l_apex - e,
                    min(z_apex, end),
                    max(z_apex, end),
                    xtol=1e-14,
                )
                for e in bounds[1:-1]
            ]
            + [end]
        )
        amp = el.amplitude[side][np.argsort(np.abs(z[side] - z_apex))]
        assert amp.size == len(bounds) - 1
        for k in range(amp.size):
            want = quad(f, min(zb[k], zb[k + 1]), max(zb[k], zb[k + 1]), epsabs=0, epsrel=1e-10)[0]
            assert amp[k] == pytest.approx(want, rel=2e-3, abs=1e-6 * abs(amp).max())
            checked += 1
    assert checked > 10
