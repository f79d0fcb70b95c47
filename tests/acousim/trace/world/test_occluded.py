"""RayCaster.occluded (Embree's occlusion query) against a ray-triangle test written
here (Moller-Trumbore over every face, in float64): a ray is occluded within a
distance exactly where its nearest face hit lies within it."""

from __future__ import annotations

import numpy as np
import trimesh

from acousim.trace.world.embree import RayCaster


def nearest_hit(triangles: np.ndarray, origins: np.ndarray, units: np.ndarray) -> np.ndarray:
    """Distance (N,) along each unit direction to the nearest triangle (inf: none)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = b - a, c - a  # (F, 3)
    best = np.full(len(origins), np.inf)
    for k, (o, d) in enumerate(zip(origins, units)):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
        s = o - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        if hit.any():
            best[k] = t[hit].min()
    return best


def test_occluded_is_a_hit_within_the_distance():
    box = trimesh.creation.box([1.0, 0.6, 0.4])
    ball = trimesh.creation.icosphere(2, 0.3)
    ball.apply_translation([1.2, 0.3, 0.1])
    mesh = trimesh.util.concatenate([box, ball])
    caster = RayCaster(mesh.triangles, threads=1)
    rng = np.random.default_rng(5)
    n = 400
    origins = rng.uniform([-2, -1.5, -1], [3, 1.5, 1], (n, 3))
    targets = rng.uniform([-0.8, -0.5, -0.4], [1.6, 0.7, 0.5], (n, 3))
    d = targets - origins
    units = d / np.linalg.norm(d, axis=1, keepdims=True)
    reach = rng.uniform(-0.2, 4.0, n)
    near = nearest_hit(mesh.triangles, origins, units)
    got = caster.occluded(origins, d * rng.uniform(0.5, 3, (n, 1)), reach)  # any length
    clear = np.abs(near - reach) > 1e-4  # away from float32's rounding of either
    expected = (near <= reach) & (reach > 0)
    assert clear.sum() > 0.95 * n
    assert 0.2 * n < expected.sum() < 0.8 * n  # both answers are tested
    np.testing.assert_array_equal(got[clear], expected[clear])


def test_occluded_with_no_rays_and_shared_among_threads():
    box = trimesh.creation.box([1.0, 1.0, 1.0])
    one, two = RayCaster(box.triangles, threads=1), RayCaster(box.triangles, threads=2)
    assert one.occluded(np.zeros((0, 3)), np.zeros((0, 3)), 1.0).shape == (0,)
    rng = np.random.default_rng(2)
    n = 90_000  # split among the threads
    origins = rng.uniform(-2, 2, (n, 3))
    d = rng.normal(size=(n, 3))
    reach = rng.uniform(0, 3, n)
    np.testing.assert_array_equal(one.occluded(origins, d, reach), two.occluded(origins, d, reach))
