"""The Doppler renderer's reference case: a two-microphone array driving at 1 m/s and
turning at 90 deg/s past four point reflectors, with air absorption and a piston
emitter; the reference signal is each path's exact time-scaled echo (rendered sample
by sample with the exact kinematics), filtered by its own path response, summed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import processing as P
from acousim.core.echoes import Echoes
from acousim.kinematics import SensorKinematics, arrivals
from acousim.kinematics.reference import render_doppler_reference
from acousim.scene import Pose
from acousim.scene.trajectory import Trajectory
from acousim.synth.response import PathResponse
from acousim.trace.motion.following import MovingPaths


@dataclass(frozen=True)
class MovingCase:
    """What a renderer takes (`echoes`, `rate`, the call `wf`, `n` samples at `fs`,
    the `response`) and the reference signal `exact` (M, n)."""

    echoes: Echoes
    rate: np.ndarray
    wf: P.Waveform
    fs: float
    n: int
    response: PathResponse
    exact: np.ndarray


def turning_past_four_points(fs: float, c: float = 343.0) -> MovingCase:
    """The case of the module docstring, at sample rate `fs` (Hz) and sound speed `c`."""
    arr = P.preset("urtis_v1")
    arr = P.Array("two", arr.positions_m[[3, 25]], np.array([0.0, 0, -0.012]))
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [1.0, 0.2, 0], [0, 0, np.deg2rad(90)])
    wf = P.rtis_call("default_20_80")
    pts = np.array([[2.0, 0.3, 0.1], [1.5, -1.0, 0.0], [3.0, 1.2, 0.2], [-1.0, 0.5, 0.0]])
    paths = MovingPaths.points(pts, np.ones(4), np.zeros((4, 3)), pose.to_world(arr.emitter_m))
    n = int(0.024 * fs)
    kin = SensorKinematics(traj, pose, arr, n / fs, 2.5e-4)
    a = arrivals(paths, kin, wf.duration_s, c, np.array([1.0, 0, 0]))
    # one length per path (the per-microphone part is the static renderer's business)
    length = np.broadcast_to(a.echoes.path_length_m.mean(axis=0), a.echoes.gain.shape)
    echoes = Echoes(a.echoes.delay_s, a.echoes.gain, length, a.echoes.order, a.echoes.angles())
    response = PathResponse(speed_of_sound_m_s=c, emitter_radius_m=0.005)
    nfft = 2 * n
    f = np.fft.rfftfreq(nfft, 1 / fs)
    exact_kin = SensorKinematics.exact(traj, pose, arr)
    exact = np.zeros((arr.n_mics, n))
    for k in range(len(paths)):
        one = render_doppler_reference(
            paths.select([k]), exact_kin, wf, fs, n, c, a.echoes.gain[:, [k]]
        )
        H = response.matrix(f, length[0, [k]], echoes.angles()[[k]])[:, 0]
        exact += np.fft.irfft(np.fft.rfft(one, nfft) * H, nfft)[:, :n]
    return MovingCase(echoes, a.rate, wf, fs, n, response, exact)
