"""The compiled mirrors and first legs of :meth:`MovingPaths.from_traced`
(:mod:`acousim.trace.motion._following_kernel`) against the numpy version to the
bit, and against the reflection's closed form."""

from __future__ import annotations

import numpy as np
import pytest

from acousim.trace.motion import following
from acousim.trace.motion.following import FirstLeg, MovingPaths
from acousim.trace.paths import KIND, TracedPaths

pytest.importorskip("numba")


def _paths(n: int, seed: int) -> TracedPaths:
    rng = np.random.default_rng(seed)
    kind = rng.integers(0, 5, n)
    order = np.where(kind == KIND.direct, 0, rng.integers(1, 4, n))
    first = rng.uniform(0.5, 9, n)
    first[rng.random(n) < 0.3] = 0.0  # image sources: their distance
    dep = rng.standard_normal((n, 3))
    return TracedPaths(
        anchor_m=rng.uniform(-8, 8, (n, 3)),
        first_leg_m=first,
        strength=rng.uniform(0.1, 1, n),
        position_m=rng.uniform(-4, 4, (n, 3)),
        order=order,
        kind=kind,
        departure=dep / np.linalg.norm(dep, axis=1, keepdims=True),
    )


@pytest.mark.parametrize("seed", [1, 2])
def test_compiled_from_traced_is_numpys_to_the_bit(seed, monkeypatch):
    paths, emitter = _paths(3000, seed), np.array([0.3, -0.2, 0.1])
    compiled = MovingPaths.from_traced(paths, emitter)
    monkeypatch.setattr(following, "optional_kernel", lambda *a: None)
    plain = MovingPaths.from_traced(paths, emitter)
    for name in ("mirror", "first_leg", "fermat_length_m"):
        a, b = getattr(compiled, name), getattr(plain, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name


def test_first_order_mirror_reflects_the_emitter_onto_its_image():
    paths, emitter = _paths(400, 3), np.array([0.3, -0.2, 0.1])
    moving = MovingPaths.from_traced(paths, emitter)
    one = np.flatnonzero((paths.kind == KIND.specular) & (paths.order == 1))
    assert one.size
    for n in one:
        u = emitter - paths.anchor_m[n]
        u /= np.sqrt(u @ u)
        assert np.allclose(moving.mirror[n], np.eye(3) - 2 * np.outer(u, u), rtol=0, atol=1e-15)
        assert moving.first_leg[n] == FirstLeg.fixed
    direct = paths.kind == KIND.direct
    assert np.array_equal(moving.mirror[direct], np.broadcast_to(np.eye(3), (direct.sum(), 3, 3)))
    assert np.all(moving.first_leg[paths.kind == KIND.point] == FirstLeg.exact)
    image = np.flatnonzero(paths.first_leg_m == 0)
    want = np.linalg.norm(paths.anchor_m[image] - emitter, axis=1)
    assert np.allclose(moving.fermat_length_m[image], want, rtol=1e-15, atol=0)
