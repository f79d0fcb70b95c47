"""The moving render's direct path summed in time while its echoes go by FFT
(:func:`acousim.synth.doppler.render_planned`): the direct path's part of the
render against the exact per-sample echo (the analytic call at the solved emission
time, :func:`~acousim.kinematics.reference.render_doppler_reference`) filtered by
its own response by FFT in the test."""

from __future__ import annotations

import numpy as np

import processing as P
from acousim.core.echoes import Echoes
from acousim.kinematics import SensorKinematics, arrivals
from acousim.kinematics.reference import render_doppler_reference
from acousim.scene import Pose
from acousim.scene.trajectory import Trajectory
from acousim.synth import doppler
from acousim.synth.doppler import render_doppler
from acousim.synth.response import PathResponse
from acousim.trace.motion.following import FirstLeg, MovingPaths

C = 343.0
FS = 450e3
ECHOES = 160  # enough that the whole render goes by FFT


def _direct(emitter: np.ndarray) -> MovingPaths:
    """The emitter -> microphone path: its anchor the emitter, moving with it."""
    return MovingPaths(
        emitter[None],
        np.zeros(1),
        np.ones(1),
        np.array([[1.0, 0, 0]]),
        np.zeros(1, int),
        np.eye(3)[None],
        np.array([FirstLeg.fixed]),
        np.zeros((1, 3)),
        np.full(1, 1e-6),
    )


def _drive():
    """Two uRTIS microphones on a sensor driving at 1 m/s and turning at 90 deg/s:
    the direct path and ECHOES weak point reflectors at 1.5-3 m (seeded)."""
    arr = P.preset("urtis_v1")
    arr = P.Array("two", arr.positions_m[[3, 25]], np.array([0.0, 0, -0.012]))
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [1.0, 0.2, 0], [0, 0, np.deg2rad(90)])
    rng = np.random.default_rng(7)
    direction = rng.normal(size=(ECHOES, 3)) * [0.3, 1, 0.3] + [1, 0, 0]
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    pts = direction * rng.uniform(1.5, 3.0, (ECHOES, 1))
    emitter = pose.to_world(arr.emitter_m)
    echoes = MovingPaths.points(pts, np.full(ECHOES, 0.05), np.zeros((ECHOES, 3)), emitter)
    paths = MovingPaths.concatenate([_direct(emitter), echoes])
    n = int(0.012 * FS)
    kin = SensorKinematics(traj, pose, arr, n / FS, 2.5e-4)
    wf = P.rtis_call("default_25_50")
    a = arrivals(paths, kin, wf.duration_s, C, np.array([1.0, 0, 0]))
    return SensorKinematics.exact(traj, pose, arr), paths, n, wf, a


def _one_length(e: Echoes, keep=slice(None)) -> Echoes:
    """`e`'s paths `keep`, each path's length the mean over the microphones (the
    response one filter a path, as the reference applies it)."""
    length = np.broadcast_to(e.path_length_m.mean(axis=0), e.gain.shape)
    return Echoes(
        e.delay_s[:, keep], e.gain[:, keep], length[:, keep], e.order[keep], e.angles()[keep]
    )


def test_direct_path_summed_in_time_against_the_per_sample_reference(monkeypatch):
    """The render of the direct path and the echoes minus that of the echoes alone
    (both by FFT: the same echo sets): the direct path as summed in time, within -60
    dB of its exact echo filtered by its response (absorption, directivity)."""
    kin, paths, n, wf, a = _drive()
    response = PathResponse(speed_of_sound_m_s=C, emitter_radius_m=0.005)
    both, echoes = _one_length(a.echoes), _one_length(a.echoes, slice(1, None))
    assert both.order[0] == 0 and np.all(echoes.order > 0)
    in_time = []
    real = doppler._planned_in_time

    def spy(plan, gains, filt_band, out, paths=None):
        in_time.append(gains.shape)
        return real(plan, gains, filt_band, out, paths=paths)

    monkeypatch.setattr(doppler, "_planned_in_time", spy)
    y_both = render_doppler(both, a.rate, wf, FS, n, response=response)
    assert len(in_time) == 1 and in_time[0][1] == 1  # the direct path alone in time
    y_echoes = render_doppler(echoes, a.rate[:, 1:], wf, FS, n, response=response)
    assert len(in_time) == 1  # the echoes by FFT
    direct = y_both - y_echoes

    nfft = 2 * n
    f = np.fft.rfftfreq(nfft, 1 / FS)
    one = render_doppler_reference(paths.select([0]), kin, wf, FS, n, C, a.echoes.gain[:, [0]])
    H = response.matrix(f, both.path_length_m[0, [0]], both.angles()[[0]])[:, 0]
    exact = np.fft.irfft(np.fft.rfft(one, nfft) * H, nfft)[:, :n]
    err = 20 * np.log10(np.linalg.norm(direct - exact) / np.linalg.norm(exact))
    assert err <= -60
