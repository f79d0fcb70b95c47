"""The signal model of eq. 1: echoes -> per-microphone signals -> a Recording.

A scene pays only for what it uses: echoes that start after the recording window
are skipped (and logged at debug level), only the samples that echoes reach are
computed, and no noise is generated at infinite SNR.
"""

from __future__ import annotations

import logging

import numpy as np

from processing import Array, Recording, Waveform
from processing.errors import InputError

from .echoes import Echoes, PointReflectors, point_echoes
from .moving import DopplerPlan, render_doppler, render_planned
from .noise import NoiseDraw, add_noise, noise_sigma
from .render import DEFAULT_INTERPOLATOR, DEFAULT_TAPS, FractionalDelay, render
from .response import PathResponse

__all__ = ["simulate", "simulate_points", "in_window"]

log = logging.getLogger(__name__)


def simulate(
    echoes: Echoes,
    array: Array,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    speed_of_sound_m_s: float = 343.0,
    snr_db: float = np.inf,
    n_measurements: int | None = None,
    seed: int | None = 0,
    emission_index: int = 0,
    interpolator: FractionalDelay = DEFAULT_INTERPOLATOR,
    taps: int = DEFAULT_TAPS,
    response: PathResponse | None = None,
    snr_reference: str = "signal",
    metadata: dict | None = None,
    doppler: np.ndarray | DopplerPlan | None = None,
) -> Recording:
    """Render echoes into a Recording, with noise at `snr_db` (eq. 2, see
    :mod:`acousim.synth.noise`).

    Parameters
    ----------
    n_measurements : int, optional
        K measurements of the static scene with independent noise: samples (K, M, T).
    response : PathResponse, optional
        Air absorption and emitter directivity per path.
    snr_reference : {'signal', 'echoes'}
        'signal': eq. 2 on the rendered signal (the paper's study).  'echoes': the
        signal power is that of the echoes alone, the direct path (order 0, tens of
        dB louder in a real sensor) left out, estimated from the path gains as if the
        echoes did not overlap: ``sum_n mean_m(g_mn^2) |H_n(f_c)|^2 E_call / (M L)``
        per microphone, with E_call the call's energy and H_n the path response at
        the band centre.
    doppler : ndarray (M, N), optional
        Time compression of each echo (a moving scene: ``tau = doppler (t - delay)``,
        see :mod:`acousim.synth.moving`); rendered by
        :func:`acousim.synth.moving.render_doppler`.  Or the
        :class:`~acousim.synth.moving.DopplerPlan` of `echoes` (made in advance by
        :func:`~acousim.synth.moving.plan_doppler` from the echoes
        :func:`in_window` keeps, with the same options).
    seed : int
        Seed of the noise generator (numpy Generator); the same seed gives the same
        bytes.
    """
    if n_samples < 1:
        raise ValueError(f"n_samples must be positive, got {n_samples}")
    if echoes.delay_s.shape[0] != array.n_mics:
        raise ValueError(
            f"echoes are for {echoes.delay_s.shape[0]} microphones, "
            f"array {array.name!r} has {array.n_mics}"
        )
    window_s = (n_samples - emission_index) / sample_rate_hz
    inside = in_window(echoes, n_samples, sample_rate_hz, emission_index)
    if not inside.all():
        if isinstance(doppler, DopplerPlan):
            raise ValueError("a Doppler plan is made of the echoes inside the window only")
        echoes = echoes.select(inside)
        doppler = None if doppler is None else doppler[:, inside]
    options = dict(
        emission_index=emission_index, interpolator=interpolator, taps=taps, response=response
    )
    rng = np.random.default_rng(seed)
    # the noise is drawn in a background thread while the echoes are rendered
    M = array.n_mics
    shape = (M, n_samples) if n_measurements is None else (n_measurements, M, n_samples)
    drawn = NoiseDraw(rng, shape) if np.isfinite(snr_db) else None
    if isinstance(doppler, DopplerPlan):
        clean = render_planned(doppler)
    elif doppler is not None:
        clean = render_doppler(echoes, doppler, waveform, sample_rate_hz, n_samples, **options)
    else:
        clean = render(echoes, waveform, sample_rate_hz, n_samples, **options)
    if np.isfinite(snr_db):
        if not np.any(clean):
            raise InputError(
                f"snr_db={snr_db} is relative to the echoes, but no echo reaches the "
                f"{window_s * 1e3:.2f} ms window"
            )
        call_samples = int(np.ceil(waveform.duration_s * sample_rate_hz))
        if snr_reference == "echoes":
            sigma = _echo_noise_sigma(echoes, waveform, sample_rate_hz, snr_db, response)
        elif snr_reference == "signal":
            sigma = noise_sigma(clean, snr_db, call_samples)
        else:
            raise ValueError(f"snr_reference must be 'signal' or 'echoes', got {snr_reference!r}")
        samples = add_noise(clean, sigma, rng, n_measurements, drawn)
    else:
        log.debug("infinite SNR: no noise generated")
        samples = (
            clean
            if n_measurements is None
            else np.broadcast_to(clean, (n_measurements, *clean.shape)).copy()
        )
    meta = {"simulated": True, "seed": seed, "snr_db": float(snr_db), "n_paths": echoes.n_paths}
    meta.update(metadata or {})
    return Recording(
        samples, sample_rate_hz, array, waveform, speed_of_sound_m_s, emission_index, meta
    )


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
    call = waveform.sampled(fs)
    power = np.mean(echoes.gain[:, echo] ** 2, axis=0)
    if response is not None and response.active:
        f_c = float(np.mean(waveform.band_hz))
        counts = None if echoes.interactions is None else echoes.interactions[echo]
        h = response.matrix(
            np.array([f_c]), echoes.path_length_m.mean(axis=0)[echo], echoes.angles()[echo], counts
        )[0]
        power = power * h**2
    p_s = float(np.sum(power) * np.sum(call**2) / call.size)
    return float(np.sqrt(p_s / 10 ** (snr_db / 10)))


def simulate_points(
    reflectors: PointReflectors,
    array: Array,
    waveform: Waveform,
    sample_rate_hz: float,
    n_samples: int,
    *,
    speed_of_sound_m_s: float = 343.0,
    spreading: str = "spherical",
    **kw,
) -> Recording:
    """Eq. 1 for point reflectors (see :func:`simulate` for the other parameters)."""
    echoes = point_echoes(reflectors, array, speed_of_sound_m_s, spreading)
    meta = {
        "reflectors": {
            "positions_m": reflectors.positions_m.tolist(),
            "strength": reflectors.strength.tolist(),
        },
        "spreading": spreading,
    }
    meta.update(kw.pop("metadata", None) or {})
    return simulate(
        echoes,
        array,
        waveform,
        sample_rate_hz,
        n_samples,
        speed_of_sound_m_s=speed_of_sound_m_s,
        metadata=meta,
        **kw,
    )
