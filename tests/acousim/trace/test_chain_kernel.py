"""The compiled steps of the ground truth's chain points (:mod:`acousim.trace.
_chain_kernel`) against the formulas written here path by path, and
:func:`acousim.trace.seen.chain_points` compiled and in numpy alike."""

from __future__ import annotations

import numpy as np
import pytest

from acousim.trace import seen as seen_module

pytest.importorskip("numba")


def test_aim_is_the_point_moved_beside_by_its_distance():
    from acousim.trace._chain_kernel import aim

    rng = np.random.default_rng(2)
    last = rng.uniform(-5, 5, (30, 3))
    todo = np.array([3, 0, 29, 7, 7, 12])
    receiver = np.array([0.2, -0.1, 0.05])
    shift = np.array([0.0, 0.01, 0.0])
    out, dist = np.empty((todo.size, 3)), np.empty(todo.size)
    aim(last, todo, receiver, shift, out, dist)
    for k, n in enumerate(todo):
        to = last[n] - receiver
        want = to + shift * (1 + np.sqrt(to @ to))
        assert np.allclose(out[k], want, rtol=0, atol=1e-14)
        assert abs(dist[k] - np.sqrt(want @ want)) < 1e-14


def test_accept_keeps_the_rays_that_met_their_face():
    from acousim.trace._chain_kernel import accept

    todo = np.array([4, 1, 7, 2, 9])
    dist = np.array([2.0, 2.0, 1.0, 3.0, 1.0])
    t = np.array([2.01, 2.2, np.inf, 3.0, 1.0])  # within 0.02 (1 + d): 1st, 4th, 5th
    face = np.array([5, 1, -1, 0, -1])  # the 5th met nothing
    face_object = np.array([10, 11, 12, 13, 14, 15])
    obj = np.full(10, -1)
    left = todo.copy()
    kept = accept(left, (t, face), dist, 0.02, face_object, obj)
    assert left[:kept].tolist() == [1, 7, 9]
    want = np.full(10, -1)
    want[4], want[2] = 15, 10
    assert obj.tolist() == want.tolist()


def test_chain_points_compiled_and_in_numpy_agree(monkeypatch):
    from pathlib import Path

    from acousim.scene import load_scene
    from acousim.simulator import Simulator

    scene = load_scene(Path(__file__).resolve().parents[3] / "scenes" / "corridor.toml")
    sim = Simulator(scene)
    pose = scene.sensor.poses[12]
    paths = sim.paths(pose)
    receiver = pose.to_world(sim.array.positions_m).mean(axis=0)
    fast = sim._chains(paths, pose, receiver)
    real = seen_module.optional_kernel
    monkeypatch.setattr(
        seen_module, "optional_kernel", lambda m, n=None: None if "chain" in m else real(m, n)
    )
    plain = sim._chains(paths, pose, receiver)
    assert (fast["object_index"] >= 0).mean() > 0.9  # nearly every path's object found
    for key in ("first_point_m", "last_point_m", "object_index"):
        assert np.array_equal(fast[key], plain[key], equal_nan=True), key
