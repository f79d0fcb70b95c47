"""The signal model of eq. 1: echoes -> per-microphone signals -> a Recording.

A scene pays only for what it uses: echoes that start after the recording window
are skipped (and logged at debug level), only the samples that echoes reach are
computed, and no noise is generated at infinite SNR.
"""

from __future__ import annotations

import logging
from functools import lru_cache

import numpy as np

from acousim.synth.doppler import DopplerPlan, render_doppler, render_planned
from acousim.synth.noise import NoiseDraw, add_noise, noise_sigma
from acousim.synth.options import DEFAULT_OPTIONS, NO_NOISE, Capture, Noise, RenderOptions
from acousim.synth.point_reflectors import Echoes, PointReflectors, point_echoes
from acousim.synth.render import render_baseband, render_with
from acousim.synth.response import PathResponse
from processing import Array, Recording, Waveform, provenance_metadata
from processing.base.errors import InputError
from processing.base.kernels import optional_kernel

__all__ = ["simulate", "simulate_points", "in_window", "Capture", "Noise", "RenderOptions"]

log = logging.getLogger(__name__)

#: the most microphones :func:`_mean_squares` sums compiled (numpy's pairwise block)
PAIRWISE_BLOCK = 128


def simulate(
    echoes: Echoes,
    capture: Capture,
    *,
    noise: Noise = NO_NOISE,
    options: RenderOptions = DEFAULT_OPTIONS,
    response: PathResponse | None = None,
    metadata: dict | None = None,
    doppler: np.ndarray | DopplerPlan | None = None,
    noise_echoes: Echoes | None = None,
) -> Recording:
    """Render echoes into a Recording of `capture` (array, call, sampling, window),
    with `noise` (eq. 2, :class:`~acousim.synth.options.Noise` states its options).

    `options`: the emission's sample, the fractional delays, the Doppler renderer's
    tolerances.  `response`: air absorption and emitter directivity per path.
    `doppler` (M, N): the time compression of each echo (a moving scene:
    ``tau = doppler (t - delay)``, :mod:`acousim.kinematics`), rendered by
    :func:`acousim.synth.doppler.render_doppler`; or the
    :class:`~acousim.synth.doppler.DopplerPlan` of `echoes` (made in advance by
    :func:`~acousim.synth.doppler.plan_doppler` from the echoes :func:`in_window`
    keeps, with the same options).  `noise_echoes`: the echoes the noise's level
    refers to (reference "echoes"; None: `echoes`), when `echoes` hold other calls
    too (a rig's crosstalk, :mod:`acousim.rig`).
    """
    cap = capture
    if cap.n_samples < 1:
        raise ValueError(f"n_samples must be positive, got {cap.n_samples}")
    if echoes.delay_s.shape[0] != cap.array.n_mics:
        raise ValueError(
            f"echoes are for {echoes.delay_s.shape[0]} microphones, "
            f"array {cap.array.name!r} has {cap.array.n_mics}"
        )
    inside = in_window(echoes, cap.n_samples, cap.sample_rate_hz, options.emission_index)
    if not inside.all():
        if isinstance(doppler, DopplerPlan):
            raise ValueError("a Doppler plan is made of the echoes inside the window only")
        echoes = echoes.select(inside)
        doppler = None if doppler is None else doppler[:, inside]
    rng = np.random.default_rng(noise.seed)
    # the noise is drawn in a background thread while the echoes are rendered
    M = cap.array.n_mics
    n = noise.n_measurements
    shape = (M, cap.n_samples) if n is None else (n, M, cap.n_samples)
    drawn = NoiseDraw(rng, shape) if np.isfinite(noise.snr_db) else None
    clean = _render(echoes, cap, options, response, doppler)
    reference = echoes if noise_echoes is None else noise_echoes
    samples = _noisy(clean, reference, cap, noise, options, response, rng, drawn)
    meta = {
        **provenance_metadata("simulated"),
        "seed": noise.seed,
        "snr_db": float(noise.snr_db),
        "n_paths": echoes.n_paths,
    }
    meta.update(metadata or {})
    return Recording(
        samples,
        cap.sample_rate_hz,
        cap.array,
        cap.waveform,
        cap.speed_of_sound_m_s,
        options.emission_index,
        meta,
    )


def _render(echoes, cap: Capture, options: RenderOptions, response, doppler) -> np.ndarray:
    """The noise-free signals (M, T): static, time-scaled by `doppler`, or planned."""
    if isinstance(doppler, DopplerPlan):
        return render_planned(doppler)
    args = (cap.waveform, cap.sample_rate_hz, cap.n_samples)
    if doppler is not None:
        return render_doppler(echoes, doppler, *args, options=options, response=response)
    if options.rate == "baseband" and response is not None and response.active:
        return render_baseband(echoes, cap, options, response, options.band_floor_db)
    return render_with(echoes, cap, options, response)


def _noisy(clean, echoes, cap: Capture, noise: Noise, options, response, rng, drawn):
    """`clean` with the noise of eq. 2 (a copy per measurement; as it is at infinite
    SNR)."""
    fs, waveform = cap.sample_rate_hz, cap.waveform
    if not np.isfinite(noise.snr_db):
        log.debug("infinite SNR: no noise generated")
        if noise.n_measurements is None:
            return clean
        return np.broadcast_to(clean, (noise.n_measurements, *clean.shape)).copy()
    if not np.any(clean):
        window_s = (cap.n_samples - options.emission_index) / fs
        raise InputError(
            f"snr_db={noise.snr_db} is relative to the echoes, but no echo reaches the "
            f"{window_s * 1e3:.2f} ms window"
        )
    call_samples = int(np.ceil(waveform.duration_s * fs))
    if noise.reference == "echoes":
        sigma = _echo_noise_sigma(echoes, waveform, fs, noise.snr_db, response)
    elif noise.reference == "signal":
        sigma = noise_sigma(clean, noise.snr_db, call_samples)
    else:
        raise ValueError(f"snr_reference must be 'signal' or 'echoes', got {noise.reference!r}")
    return add_noise(clean, sigma, rng, noise.n_measurements, drawn)


def in_window(
    echoes: Echoes, n_samples: int, sample_rate_hz: float, emission_index: int = 0
) -> np.ndarray:
    """Which paths (N,) are heard in a recording of `n_samples` samples: they start
    before its end at some microphone, with a nonzero gain there (a point reflector
    of strength 0 adds nothing). The others are skipped, logged at debug level."""
    window_s = (n_samples - emission_index) / sample_rate_hz
    if not echoes.n_paths:
        return np.zeros(0, bool)
    inside = np.any((echoes.delay_s < window_s) & (echoes.gain != 0), axis=0)
    if not inside.all():
        log.debug(
            "skipped %d of %d paths, silent or arriving after the %.2f ms window",
            int((~inside).sum()),
            echoes.n_paths,
            window_s * 1e3,
        )
    return inside


def _echo_noise_sigma(
    echoes: Echoes, waveform: Waveform, fs: float, snr_db: float, response: PathResponse | None
) -> float:
    echo = echoes.order > 0
    if not echo.any():
        raise InputError("snr_reference='echoes' but the scene has no echo besides the direct path")
    energy, size = _call_energy(waveform, float(fs))
    power = _mean_squares(echoes.gain, echo)
    if response is not None and response.active:
        f_c = float(np.mean(waveform.band_hz))
        counts = None if echoes.interactions is None else echoes.interactions[echo]
        h = response.matrix(
            np.array([f_c]), echoes.path_length_m.mean(axis=0)[echo], echoes.angles()[echo], counts
        )[0]
        power = power * h**2
    p_s = float(np.sum(power) * energy / size)
    return float(np.sqrt(p_s / 10 ** (snr_db / 10)))


def _mean_squares(gain: np.ndarray, paths: np.ndarray) -> np.ndarray:
    """The mean over the microphones of the squared gains (M, N) of the `paths` (N,
    bool): compiled (:mod:`._signal_kernel`, numpy's summation order: the same
    bits) for every path, then selected, or in numpy (its copy of the paths'
    columns)."""
    kernel = optional_kernel("acousim.synth._signal_kernel", "mean_squares")
    if kernel is None or gain.shape[0] > PAIRWISE_BLOCK:
        return np.mean(gain[:, paths] ** 2, axis=0)
    out = np.empty(gain.shape[1])
    kernel(np.asarray(gain, float), out)
    return out[paths]


@lru_cache(maxsize=16)
def _call_energy(waveform: Waveform, fs: float) -> tuple[np.float64, int]:
    """The sum of squares of the call sampled at `fs` (Hz) and its sample count:
    the same for every pose of a scene, computed once."""
    call = waveform.sampled(fs)
    return np.sum(call**2), call.size


def simulate_points(
    reflectors: PointReflectors,
    array: Array,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    speed_of_sound_m_s: float = 343.0,
    spreading: str = "spherical",
    noise: Noise = NO_NOISE,
) -> Recording:
    """Eq. 1 for point reflectors (see :func:`simulate`; the default options)."""
    echoes = point_echoes(reflectors, array, speed_of_sound_m_s, spreading)
    meta = {
        "reflectors": {
            "positions_m": reflectors.positions_m.tolist(),
            "strength": reflectors.strength.tolist(),
        },
        "spreading": spreading,
    }
    capture = Capture(array, waveform, sample_rate_hz, n_samples, speed_of_sound_m_s)
    return simulate(echoes, capture, noise=noise, metadata=meta)
