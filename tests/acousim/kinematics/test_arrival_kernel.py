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


def _instants_case(turn_deg_s: float = 90.0):
    """A turning, moving array (urtis_v1) and 60 anchors, three of them on the
    emitter (the direct path: 2 cm, the largest curvature of the equation), with
    when each instant's sample leaves them (s): (kin, t_r (3, N), A (3, 3, N))."""
    arr = P.preset("urtis_v1")
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [1.5, -0.5, 0.1], np.deg2rad([0, 0, turn_deg_s]))
    kin = SensorKinematics(traj, pose, arr, 0.04, TABLE_STEP_S)
    rng = np.random.default_rng(11)
    N = 60
    anchor = np.column_stack([rng.uniform(0.3, 6, N), rng.uniform(-3, 3, N), rng.uniform(-1, 1, N)])
    anchor[:3] = arr.emitter_m
    leave0 = rng.uniform(0, 2e-3, N)
    leave0[:3] = 0.0
    duration = 2.5e-3
    t_r = np.stack([leave0, leave0 + duration, leave0 + duration / 2])
    return kin, t_r, np.repeat(anchor.T[None], 3, axis=0), duration


def _reception_by_fixed_point(kin, mic, t_r, anchor):
    """The reception times (N,) at microphone `mic` of sound leaving `anchor` (N, 3)
    at `t_r` (N,): the fixed point of ``t = t_r + |m(t) - A| / c`` with m(t) from
    the trajectory itself (a contraction of ratio v / c), iterated to the last bit."""
    local = kin.array.positions_m[[mic]]
    t = t_r.copy()
    for _ in range(60):
        where = kin.trajectory.to_world(local, kin.t0 + t)[:, 0]
        new = t_r + np.linalg.norm(where - anchor, axis=1) / C
        if np.array_equal(new, t):
            break
        t = new
    return t


def _fast_turn_case():
    """:func:`_instants_case` turning at 360 deg/s: the kinematics' polynomial of
    degree 5 (the kernel's loops of DEGREE)."""
    return _instants_case(360.0)


def _through_poses_case():
    """:func:`_instants_case` on a trajectory through poses (a cubic per segment, a
    slow turn: a polynomial of degree 3, the kernel's loops of LOW)."""
    kin, t_r, A, duration = _instants_case()
    poses = [Pose([0.0, 0, 0]), Pose([0.1, 0.02, 0], 0.03, time_s=0.1)]
    poses.append(Pose([0.2, 0, 0], time_s=0.2))
    low = SensorKinematics(Trajectory.through(poses), poses[0], kin.array, 0.04, TABLE_STEP_S)
    return low, t_r, A, duration


@pytest.mark.parametrize("case", [_instants_case, _fast_turn_case, _through_poses_case])
def test_fused_instants_solve_the_retarded_time_equation(case):
    from acousim.kinematics._arrival_kernel import LOW, solve_arrivals

    kin, t_r, A, duration = case()
    assert kin.poly is not None
    # each of the kernel's two compiled degrees (LOW and DEGREE) is met
    assert (kin.degree > LOW) == (case is _fast_turn_case)
    out = solve_arrivals(
        t_r, A, duration, kin.mic_poly, kin.mic_poly_v, kin.mid, kin.half, C, mv.NEWTON_STOP_S
    )
    assert out.shape == (3, kin.array.n_mics, t_r.shape[1])
    for q in range(3):
        for m in (0, 1, 9, 17, 29):  # the first microphone, its neighbour, others
            ref = _reception_by_fixed_point(kin, m, t_r[q], A[q].T)
            # the polynomial is within 1e-10 m of the trajectory: 3e-13 s
            assert np.abs(out[q, m] - ref).max() < 1e-12


def test_arrivals_compiled_and_array_versions_agree(monkeypatch):
    """The fused solve against the three array solves (numpy) it replaces."""
    kin, t_r, A, duration = _instants_case()
    N = t_r.shape[1]
    anchor = A[0].T
    paths = mv.MovingPaths(
        anchor,
        C * t_r[0],
        np.ones(N),
        np.tile([1.0, 0, 0], (N, 1)),
        np.ones(N, int),
        np.tile(np.eye(3), (N, 1, 1)),
        np.zeros(N, int),
        np.zeros((N, 3)),
        np.maximum(C * t_r[0], 1.0),
    )
    axis = np.array([1.0, 0, 0])
    fast = mv.arrivals(paths, kin, duration, C, axis)
    monkeypatch.setattr(mv, "_kernel", lambda name: None)
    plain = mv.arrivals(paths, kin, duration, C, axis)
    # both within the Newton bound (1e-12 s: the direct path's last leg is 2 mm at
    # some microphones, so its gain moves by c 1e-12 / 2 mm relative)
    assert np.abs(fast.echoes.delay_s - plain.echoes.delay_s).max() < 1e-12
    assert np.abs(fast.curvature_s - plain.curvature_s).max() < 1e-12
    assert np.abs(fast.rate - plain.rate).max() < 1e-9
    assert np.abs(fast.echoes.path_length_m - plain.echoes.path_length_m).max() < C * 1e-12
    assert np.allclose(fast.echoes.gain, plain.echoes.gain, rtol=1e-6, atol=0)
    assert np.array_equal(fast.leave_s, plain.leave_s)
    assert np.array_equal(fast.anchor_m, plain.anchor_m)


def test_echoes_are_the_stated_formulas_of_the_reception_times():
    """The compiled echoes against the formulas written here on the compiled
    reception times (the same solve)."""
    from acousim.kinematics._arrival_kernel import solve_arrivals, solve_echoes

    kin, t_r, A, duration = _instants_case()
    rng = np.random.default_rng(3)
    N = t_r.shape[1]
    first = C * t_r[0] * rng.uniform(0.2, 0.8, N)
    first[3] = 1e3  # a last leg below 1 um: held at 1 um
    amplitude = rng.uniform(0.1, 2, N)
    args = (t_r, A, duration, kin.mic_poly, kin.mic_poly_v, kin.mid, kin.half, C, 1e-6)
    t = solve_arrivals(*args)
    delay, gain, length, rate, curvature = solve_echoes(*args, first, amplitude)
    for m in (0, 1, 13, 29):
        for n in range(N):
            last = max(C * t[0, m, n] - first[n], 1e-6)
            bend = t[2, m, n] - (t[0, m, n] + t[1, m, n]) / 2
            assert length[m, n] == pytest.approx(first[n] + last, rel=1e-15)
            assert gain[m, n] == pytest.approx(amplitude[n] / last, rel=1e-15)
            assert curvature[m, n] == pytest.approx(bend, rel=1e-12, abs=1e-20)
            assert delay[m, n] == pytest.approx(t[0, m, n] + 2 * bend / 3, rel=1e-15)
            assert rate[m, n] == pytest.approx(duration / (t[1, m, n] - t[0, m, n]), rel=1e-12)
    assert gain[:, 3].max() == pytest.approx(amplitude[3] / 1e-6)


def test_still_anchors_leave_as_the_stated_laws():
    """The compiled start of the last legs of still anchors (`leaving_still`) against
    the laws of acousim.trace.motion.following written here per path: the anchor
    moves by J de, the first leg held, by Fermat's law to second order, or exact."""
    from acousim.kinematics._arrival_kernel import leaving_still

    rng = np.random.default_rng(5)
    N, tau = 40, np.array([0.0, 2.5e-3, 1.25e-3])
    a0 = rng.uniform(-4, 4, (N, 3))
    J = np.linalg.qr(rng.normal(size=(N, 3, 3)))[0]
    f0, lf = rng.uniform(0.5, 5, N), rng.uniform(1, 8, N)
    mode = np.arange(N) % 3
    dep = rng.normal(size=(N, 3))
    dep /= np.linalg.norm(dep, axis=1, keepdims=True)
    e0 = np.array([0.1, -0.2, 0.3])
    e = e0 + np.outer(tau, [1.5, -0.4, 0.2])  # the emitter moving at 1.6 m/s
    out = (np.empty((3, N)), np.empty((3, 3, N)), np.empty(N))
    leaving_still(a0, J, (f0, mode, lf), dep, (e, e0), tau, C, out)
    for q in range(3):
        de = e[q] - e0
        for n in range(N):
            anchor = a0[n] + J[n] @ de
            first = [
                f0[n],
                f0[n] - dep[n] @ de + (de @ de - (dep[n] @ de) ** 2) / (2 * lf[n]),
                np.linalg.norm(anchor - e[q]),
            ][mode[n]]
            assert np.allclose(out[1][q, :, n], anchor, rtol=0, atol=1e-14)
            assert abs(out[0][q, n] - (tau[q] + first / C)) < 1e-16
            if q == 0:
                assert abs(out[2][n] - first) < 1e-14
