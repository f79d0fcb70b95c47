"""The exact echoes of a measurement in motion, per output sample: the reference the
fast renderer (:mod:`acousim.synth.doppler`) is measured against.

Per output sample at 64 times the sample rate, the emission time solved exactly
(Newton on the retarded-time equation with the continuous trajectory), the analytic
call evaluated there, low-passed at 0.8 Nyquist and decimated, as the static
renderer's reference.  Cost grows as M N L 64; for tests and benchmarks.
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sfft

from acousim.kinematics.retarded import arrival_times
from acousim.kinematics.sensor import SensorKinematics
from acousim.trace.motion.following import MovingPaths
from processing import Waveform
from processing.sensor.calls import ANTI_ALIAS_CUTOFF

__all__ = ["render_doppler_reference"]


def render_doppler_reference(
    paths: MovingPaths,
    sensor: SensorKinematics,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    speed_of_sound_m_s: float,
    gain: np.ndarray,
    *,
    oversample: int = 64,
) -> np.ndarray:
    """The exact echoes (M, T): per output sample at `oversample` times the rate the
    emission time solved on the continuous trajectory of `sensor`
    (:meth:`SensorKinematics.exact`), the analytic call evaluated there times `gain`
    (M, N), low-passed at 0.8 Nyquist and decimated.  No air absorption or
    directivity."""
    c = speed_of_sound_m_s
    fs_fine = sample_rate_hz * oversample
    n_fine = n_samples * oversample
    kin = sensor
    if kin.step is not None:
        raise ValueError("the reference needs the exact kinematics: SensorKinematics.exact")
    M, N = kin.array.n_mics, len(paths)
    T = waveform.duration_s
    out = np.zeros((M, n_samples))
    for m in range(M):
        fine = np.zeros(n_fine)
        for k in range(N):
            one = paths.select(slice(k, k + 1))
            ends, _, _ = arrival_times(one, kin, np.array([[0.0, T]]), c, mic=m)
            t_a, t_b = ends[0]
            i0 = max(int(np.floor(t_a * fs_fine)) - 2, 0)
            i1 = min(int(np.ceil(t_b * fs_fine)) + 2, n_fine)
            if i1 <= i0:
                continue
            t = np.arange(i0, i1) / fs_fine
            a = T / (t_b - t_a)
            tau = a * (t - t_a)
            for _ in range(12):  # Newton with the secant slope
                arr, _, _ = arrival_times(one, kin, tau[None, :], c, mic=m)
                step = a * (t - arr[0])
                tau = tau + step
                if np.max(np.abs(step)) < 1e-16:
                    break
            fine[i0:i1] += gain[m, k] * waveform.at(tau)
        spec = sfft.rfft(fine)
        spec[int(ANTI_ALIAS_CUTOFF * n_samples / 2) + 1 :] = 0.0
        out[m] = sfft.irfft(spec, n_fine)[::oversample]
    return out
