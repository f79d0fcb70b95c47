"""The compiled Newton solve of the reception times (numba) against the array
version it replaces (numpy), and both against the retarded-time equation itself."""

from __future__ import annotations

import numpy as np
import pytest

import processing as P
from acousim.kinematics import retarded as mv
from acousim.kinematics.sensor import TABLE_STEP_S, SensorKinematics
from acousim.scene import Pose
from acousim.scene.trajectory import Trajectory

pytest.importorskip("numba")

C = 343.0


def _case():
    arr = P.preset("urtis_v1")
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [2.0, 0.4, 0], np.deg2rad([0, 0, 180]))
    kin = SensorKinematics(traj, pose, arr, 0.04, TABLE_STEP_S)
    rng = np.random.default_rng(7)
    N = 200
    anchor = np.column_stack([rng.uniform(0.5, 5, N), rng.uniform(-2, 2, N), rng.uniform(-1, 1, N)])
    t_r = np.broadcast_to(rng.uniform(0, 2e-3, N), (arr.n_mics, N))
    return kin, t_r, anchor[None]


def test_compiled_newton_agrees_with_the_array_version_and_the_equation(monkeypatch):
    kin, t_r, anchor = _case()
    assert kin.poly is not None
    fast = mv._newton_by_axis(kin, t_r, anchor, C, None)
    monkeypatch.setattr(mv, "_arrival_kernel", lambda: None)
    plain = mv._newton_by_axis(kin, t_r, anchor, C, None)
    assert np.abs(fast - plain).max() < 1e-12
    # the retarded-time equation t = t_r + |m(t) - A| / c, m(t) from the trajectory
    for m in (0, 17, 29):
        mics = kin.trajectory.to_world(kin.array.positions_m[[m]], kin.t0 + fast[m])[:, 0]
        residual = fast[m] - t_r[m] - np.linalg.norm(mics - anchor[0], axis=1) / C
        assert np.abs(residual).max() < 1e-10
