"""Independent references the renderers' tests share: point echoes with a direction
per path, and each path filtered by its own response and delayed exactly in the
frequency domain (written here, not taken from the renderers)."""

from __future__ import annotations

import numpy as np
from scipy import fft as sfft

import processing as P
from acousim.core.echoes import Echoes
from acousim.synth.point_reflectors import PointReflectors, point_echoes
from acousim.synth.response import PathResponse

C = 343.0


def echoes_ahead(arr: P.Array, n: int = 40, seed: int = 4, near_m: float = 0.5) -> Echoes:
    """`n` point reflectors at `near_m`-5 m ahead of `arr` (seeded), each path's angle
    off the array's axis (+x) as its emission angle, rad."""
    rng = np.random.default_rng(seed)
    refl = PointReflectors(rng.uniform([near_m, -2, -1], [5, 2, 1], (n, 3)), 1.0)
    e = point_echoes(refl, arr, C)
    theta = np.arccos(refl.positions_m[:, 0] / np.linalg.norm(refl.positions_m, axis=1))
    return Echoes(e.delay_s, e.gain, e.path_length_m, e.order, theta)


def filtered_per_path(
    e: Echoes, call: P.Waveform, response: PathResponse, fs: float, n_samples: int
) -> np.ndarray:
    """(M, n_samples) the echoes of `call` at `fs` (Hz), each path and microphone
    filtered by `response` and delayed exactly by its phase in the frequency domain."""
    x, start = call.band_limited(fs)
    n = sfft.next_fast_len(n_samples + x.size + 512)
    W = sfft.rfft(x, n)
    f = np.arange(W.size) * fs / n
    spec = np.zeros((e.delay_s.shape[0], W.size), complex)
    for k in range(e.n_paths):
        angle = np.full(e.delay_s.shape[0], e.emitter_angle_rad[k])
        H = response.matrix(f, e.path_length_m[:, k], angle).T
        delay = e.delay_s[:, k][:, None] + start / fs
        spec += W * H * e.gain[:, k][:, None] * np.exp(-2j * np.pi * f * delay)
    return sfft.irfft(spec, n)[:, :n_samples]
