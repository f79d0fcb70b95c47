"""The Doppler renderer at complex baseband (``render_rate = "baseband"``,
:mod:`acousim.synth.baseband`) against independent references: the exact per-sample
echo (the analytic call at the solved emission time) and each path filtered by its
own response by FFT."""

from __future__ import annotations

import numpy as np
import pytest

import processing as P
from acousim.core.echoes import Echoes
from acousim.kinematics import SensorKinematics, arrivals
from acousim.kinematics.reference import render_doppler_reference
from acousim.scene import Pose
from acousim.scene.trajectory import Trajectory
from acousim.synth import baseband
from acousim.synth.doppler import render_doppler
from acousim.synth.options import RenderOptions
from acousim.synth.response import PathResponse
from acousim.trace.motion.following import MovingPaths
from tests.acousim.synth.references import echoes_ahead, filtered_per_path

C = 343.0
FS = 450e3
BASEBAND = RenderOptions(rate="baseband")


def _drive(n_paths: int):
    """Two microphones of the uRTIS on a sensor driving at 1 m/s and turning at
    90 deg/s; `n_paths` point reflectors at 1.5-3 m (seeded)."""
    arr = P.preset("urtis_v1")
    arr = P.Array("two", arr.positions_m[[3, 25]], np.array([0.0, 0, -0.012]))
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [1.0, 0.2, 0], [0, 0, np.deg2rad(90)])
    rng = np.random.default_rng(5)
    direction = rng.normal(size=(n_paths, 3)) * [0.3, 1, 0.3] + [1, 0, 0]
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    pts = direction * rng.uniform(1.5, 3.0, (n_paths, 1))
    paths = MovingPaths.points(
        pts, np.ones(n_paths), np.zeros((n_paths, 3)), pose.to_world(arr.emitter_m)
    )
    n = int(0.024 * FS)
    kin = SensorKinematics(traj, pose, arr, n / FS, 2.5e-4)
    a = arrivals(paths, kin, P.rtis_call("default_25_50").duration_s, C, np.array([1.0, 0, 0]))
    return arr, pose, traj, paths, n, a


def _db(a: np.ndarray, b: np.ndarray) -> float:
    return float(20 * np.log10(np.linalg.norm(a - b) / np.linalg.norm(b)))


def test_baseband_renderer_against_the_per_sample_reference():
    """Without a path response: within -58 dB of the exact echoes (the band at its
    default -60 dB floor: the call's energy outside it is -65 dB)."""
    arr, pose, traj, paths, n, a = _drive(5)
    wf = P.rtis_call("default_25_50")
    fast = render_doppler(a.echoes, a.rate, wf, FS, n, options=BASEBAND)
    exact = render_doppler_reference(
        paths, SensorKinematics.exact(traj, pose, arr), wf, FS, n, C, a.echoes.gain
    )
    assert _db(fast, exact) <= -58


def test_baseband_renderer_with_absorption_and_directivity_against_exact_filtering():
    """Doppler, absorption and directivity: each path's exact echo filtered by its own
    response (FFT, here); the band floor sets the error (a wider band, a smaller one)."""
    arr, pose, traj, paths, n, a = _drive(4)
    wf = P.rtis_call("default_25_50")
    length = np.broadcast_to(a.echoes.path_length_m.mean(axis=0), a.echoes.gain.shape)
    echoes = Echoes(a.echoes.delay_s, a.echoes.gain, length, a.echoes.order, a.echoes.angles())
    response = PathResponse(speed_of_sound_m_s=C, emitter_radius_m=0.005)
    nfft = 2 * n
    f = np.fft.rfftfreq(nfft, 1 / FS)
    exact = np.zeros((2, n))
    kin = SensorKinematics.exact(traj, pose, arr)
    for k in range(len(paths)):
        one = render_doppler_reference(paths.select([k]), kin, wf, FS, n, C, a.echoes.gain[:, [k]])
        H = response.matrix(f, length[0, [k]], echoes.angles()[[k]])[:, 0]
        exact += np.fft.irfft(np.fft.rfft(one, nfft) * H, nfft)[:, :n]
    errors = []
    for floor in (-40.0, -60.0):
        options = RenderOptions(rate="baseband", band_floor_db=floor)
        fast = render_doppler(echoes, a.rate, wf, FS, n, response=response, options=options)
        errors.append(_db(fast, exact))
    assert errors[1] <= -58
    assert errors[0] > errors[1]


def test_kernel_transform_matches_a_direct_sum():
    """The kernel's Fourier transform (quadrature) against the sum of its samples
    over a fine grid (the Riemann sum of a smooth compact function)."""
    g = baseband.grid(4000, 500, 200, baseband.TAPS, baseband.OVERSAMPLING)
    x = np.linspace(-baseband.TAPS / 2, baseband.TAPS / 2, 200001)
    phi = baseband._phi(x, g.width, g.beta)
    for k in (0, 50, 200):
        direct = np.sum(phi * np.cos(2 * np.pi * k / g.nb * x)) * (x[1] - x[0])
        assert g.psi[k + g.half] == pytest.approx(direct, rel=1e-6)


def test_static_baseband_render_matches_exact_per_path_filtering():
    """A static scene's echoes (40 point reflectors, absorption and directivity) at
    complex baseband against each path filtered by its own response and delayed
    exactly in the frequency domain (written here): the band floor sets the error."""
    from acousim.synth.options import Capture
    from acousim.synth.render import render_baseband

    arr = P.ura(2, 2, 3.85e-3)
    wf = P.rtis_call("default_25_50")
    e = echoes_ahead(arr)
    resp = PathResponse(emitter_radius_m=0.004)
    ref = filtered_per_path(e, wf, resp, FS, 16384)
    capture = Capture(arr, wf, FS, 16384, C)
    errors = [
        _db(render_baseband(e, capture, BASEBAND, resp, floor), ref) for floor in (-40.0, -60.0)
    ]
    assert errors[1] <= -58
    assert errors[0] > errors[1]


def test_the_old_fast_point_still_imports_with_a_warning():
    """The deprecated fast point (one "fast" now: the quality preset) still names
    settings a scene accepts, with valid values, for one version."""
    from acousim.scene import fast
    from acousim.scene.model import Simulation

    with pytest.warns(DeprecationWarning, match='quality = "fast"'):
        settings = fast.FAST_SETTINGS
    sim = Simulation(**settings)
    assert sim.render_rate == "baseband"
    with pytest.raises(Exception, match="render_rate"):
        Simulation(render_rate="quarter")
