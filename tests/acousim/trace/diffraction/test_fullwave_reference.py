"""The full-wave reference's own pieces that need no bempp: the exact rigid-sphere
series against its two closed-form limits, and the meshes (closed, outward)."""

import numpy as np
import pytest

from tests.oracles import fullwave_meshes as geometry
from tests.oracles.sphere_series import rigid_sphere_monostatic


def test_sphere_series_matches_rayleigh_scattering_when_small():
    """ka << 1, far away: a rigid (incompressible, immovable) sphere scatters as a
    monopole -k^2 a^3 / 3 and a dipole -k^2 a^3 / 2 in the back direction (Rayleigh;
    Morse & Ingard 8.2), so p_s = -5/6 k^2 a^3 e^{2ikr} / (4 pi r^2)."""
    a, r = 1e-3, 200.0
    k = np.array([5.0, 20.0])  # ka = 0.005, 0.02; kr = 1000, 4000
    p = rigid_sphere_monostatic(k, a, r)
    rayleigh = -5 / 6 * k**2 * a**3 * np.exp(2j * k * r) / (4 * np.pi * r**2)
    np.testing.assert_allclose(p, rayleigh, rtol=2e-3)


def test_sphere_series_tends_to_geometric_optics_when_large():
    """ka >> 1: the specular echo of a convex mirror, a / (2 d (d + a)) / (4 pi) in
    magnitude with d the distance to the surface (creeping waves add a small ripple)."""
    a, r = 0.1, 0.5
    d = r - a
    k = 2 * np.pi * np.array([40e3, 80e3]) / 343.0  # ka = 73, 147
    p = rigid_sphere_monostatic(k, a, r)
    go = a / (2 * d * (d + a)) / (4 * np.pi)
    np.testing.assert_allclose(np.abs(p), go, rtol=0.05)


@pytest.mark.parametrize(
    "mesh, volume",
    [
        (geometry.box((0.04, 0.03, 0.02), 0.004), 0.04 * 0.03 * 0.02),
        (geometry.sphere(0.02, 0.002), 4 / 3 * np.pi * 0.02**3),
    ],
)
def test_closed_meshes_are_watertight_and_outward(mesh, volume):
    v, t = mesh
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    directed = set(map(tuple, edges))
    assert len(directed) == len(edges)  # no edge used twice in one direction
    assert all((b, a) in directed for a, b in edges)  # each met once the other way
    assert geometry.outward_volume(v, t) == pytest.approx(volume, rel=0.01)
