"""The compiled first-order elements (:mod:`acousim.trace.diffraction.element_kernel`,
used by :func:`acousim.trace.diffraction.btm.many_edge_elements`): bit for bit those
of the numpy form (the same operations without the kernel) on random wedges, with
tapered ends, a longest path and sources on the edge line among them; and their
sum against the BTM line integral written out here (a fine midpoint rule over the
edge of the integrand of Svensson et al. 1999); the compiled bound of an edge's
elements (:func:`acousim.trace.diffraction.first_order.edge_bound`) bit for bit
that of numpy."""

from __future__ import annotations

import numpy as np
import pytest

import acousim.trace.diffraction.btm as btm
import acousim.trace.diffraction.first_order as first_order
from acousim.scene.model import Diffraction
from acousim.trace.diffraction.btm import ElementLimits, Wedge, many_edge_elements
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions
from acousim.trace.world.edges import find_edges
from tests.acousim.trace.diffraction.test_first_order_bound import _random_objects

pytest.importorskip("numba")


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _wedges(rng, n: int) -> Wedge:
    start = rng.uniform(-1, 1, (n, 3))
    axis = _unit(rng.normal(size=(n, 3)))
    end = start + rng.uniform(0.005, 1.5, (n, 1)) * axis
    face = _unit(np.cross(axis, rng.normal(size=(n, 3))))
    terms = rng.uniform(0.3, 1, (n, 4)) * (rng.random((n, 4)) < 0.8)
    angle = rng.uniform(np.pi, 2 * np.pi, n)
    return Wedge(start, end, face, np.cross(axis, face), angle, terms=terms)


@pytest.mark.parametrize("limits", [ElementLimits(), ElementLimits(step_m=2e-4, max_path_m=3.0)])
def test_compiled_elements_are_those_of_numpy(monkeypatch, limits):
    rng = np.random.default_rng(11)
    wedges = _wedges(rng, 40)
    source = rng.uniform(-2, 2, (40, 3))
    source[3] = wedges.start_m[3] - 0.5 * (wedges.end_m[3] - wedges.start_m[3])  # on the line
    receiver = np.array([0.3, -1.2, 0.8])
    got, rows = many_edge_elements(wedges, source, receiver, limits)
    assert len(got) > 1000 and np.unique(rows).size > 5
    monkeypatch.setattr(btm, "optional_kernel", lambda name: None)
    want, want_rows = many_edge_elements(wedges, source, receiver, limits)
    np.testing.assert_array_equal(rows, want_rows)
    for name in ("point_m", "first_leg_m", "second_leg_m", "amplitude"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)


def test_elements_sum_to_the_line_integral():
    """A 6 cm edge along z of a 270-degree wedge (face 1 along x), lit from theta 60
    degrees and heard at 200 (no boundary near): the elements' amplitudes sum to
    -(nu / 4 pi) int sum_i beta_i / (m l) dz over the edge."""
    length, wedge_rad = 0.06, 1.5 * np.pi
    nu = np.pi / wedge_rad
    (rs, ts, zs), (rr, tr, zr) = (1.0, np.pi / 3, 0.02), (0.8, np.radians(200), 0.035)

    def point(r, t, z):
        return np.array([r * np.cos(t), r * np.sin(t), z])

    wedge = Wedge(
        np.zeros((1, 3)), np.array([[0, 0, length]]), np.array([[1.0, 0, 0]]),
        np.array([[0, 1.0, 0]]), np.array([wedge_rad]),
    )  # fmt: skip
    el, _ = many_edge_elements(
        wedge, point(rs, ts, zs), point(rr, tr, zr), ElementLimits(step_m=2e-5)
    )
    # the integrand on a fine grid (midpoints)
    n = 400_000
    z = (np.arange(n) + 0.5) * length / n
    m, l_ = np.hypot(rs, z - zs), np.hypot(rr, z - zr)
    cosh_eta = ((z - zs) * (z - zr) + m * l_) / (rs * rr)
    cosh_nu_eta = np.cosh(nu * np.arccosh(np.maximum(cosh_eta, 1.0)))
    beta = sum(
        np.sin(nu * phi) / (cosh_nu_eta - np.cos(nu * phi))
        for phi in (np.pi + ts + tr, np.pi + ts - tr, np.pi - ts + tr, np.pi - ts - tr)
    )
    want = -(nu / (4 * np.pi)) * np.sum(beta / (m * l_)) * length / n
    assert el.amplitude.sum() == pytest.approx(want, rel=1e-4)


@pytest.mark.parametrize("seed", range(4))
def test_compiled_edge_bound_is_that_of_numpy(monkeypatch, seed):
    """first_order.edge_bound compiled and in numpy on random boxes and plates (that
    it bounds every element: ``test_first_order_bound.py``)."""
    rng = np.random.default_rng(seed)
    mesh = _random_objects(rng)
    geometry = DiffractingGeometry(find_edges(mesh), rng.uniform(0.2, 1.0, len(mesh.faces)))
    for _ in range(4):
        emitter = rng.uniform(-4, 4, 3)
        receiver = emitter + rng.normal(0, 0.01, 3)
        options = DiffractionOptions(max_path_m=20.0, settings=Diffraction(step_m=1e-3, order=1))
        ctx = StageContext(geometry, None, emitter, receiver, options)
        keep, wedge = geometry.edges.oriented(emitter, receiver)
        rows = np.flatnonzero(keep)
        got = first_order.edge_bound(ctx, wedge, rows, emitter)
        with monkeypatch.context() as m:
            m.setattr(first_order, "optional_kernel", lambda name: None)
            want = first_order.edge_bound(ctx, wedge, rows, emitter)
        assert rows.size > 0
        np.testing.assert_array_equal(got, want)
