"""What a rendering is made with, declared once: the capture (array, call, sampling,
window), the renderer's options and the noise (:func:`acousim.synth.signal_model.simulate`,
:mod:`acousim.synth.doppler`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from acousim.core.rendering import (
    COMPRESS_TOLERANCE,
    DEFAULT_INTERPOLATOR,
    FractionalDelay,
    RenderDomain,
    RenderRate,
)
from acousim.synth.render import DEFAULT_TAPS
from processing import Array, Waveform

__all__ = [
    "Capture",
    "Noise",
    "RenderOptions",
    "DOPPLER_TOLERANCE",
    "COMPRESS_TOLERANCE",
    "SnrReference",
    "RenderRate",
    "RenderDomain",
    "DEFAULT_OPTIONS",
    "NO_NOISE",
]

#: relative error of interpolating the time-scaled call between Doppler nodes (a
#: bound at the call's top frequency: the renderer's error stays far below it)
DOPPLER_TOLERANCE = 1e-3
SnrReference = Literal["signal", "echoes"]
"""What `Noise.snr_db` is relative to (see :func:`acousim.synth.signal_model.simulate`)."""


@dataclass(frozen=True)
class Capture:
    """What records: `array`, the `waveform` it emits, `sample_rate_hz` (Hz),
    `n_samples` per channel and the `speed_of_sound_m_s` (m/s) of the air."""

    array: Array
    waveform: Waveform
    sample_rate_hz: float
    n_samples: int
    speed_of_sound_m_s: float = 343.0


@dataclass(frozen=True)
class RenderOptions:
    """How echoes become samples.

    emission_index: the sample of the start of the emission; interpolator, taps:
    the fractional delays (:mod:`acousim.synth.render`); doppler_tolerance,
    compress_tolerance: the Doppler renderer's node interpolation and gain-set
    compression (:mod:`acousim.synth.doppler`); rate: the Doppler renderer at the
    sample rate ('full') or at complex baseband ('baseband', :mod:`acousim.synth.baseband`:
    the bins within band_floor_db (dB, power) of the strongest); domain: where a
    full-rate render, still or moving, sums the echoes ('frequency', 'time' or
    'auto', the cheaper by estimate: :mod:`acousim.synth.timedomain`)."""

    emission_index: int = 0
    interpolator: FractionalDelay = DEFAULT_INTERPOLATOR
    taps: int = DEFAULT_TAPS
    doppler_tolerance: float = DOPPLER_TOLERANCE
    compress_tolerance: float = COMPRESS_TOLERANCE
    rate: RenderRate = "full"
    band_floor_db: float = -60.0
    domain: RenderDomain = "auto"


@dataclass(frozen=True)
class Noise:
    """The sensor noise (eq. 2, :mod:`acousim.synth.noise`): `snr_db` (inf: none),
    drawn from a numpy Generator seeded with `seed` (the same seed, the same bytes);
    `n_measurements` K measurements of the static scene with independent noise
    (samples (K, M, T)), None: one (M, T).

    `reference`: 'signal', eq. 2 on the rendered signal (the paper's study);
    'echoes', the signal power is that of the echoes alone, the direct path (order
    0, tens of dB louder in a real sensor) left out, estimated from the path gains as
    if the echoes did not overlap: ``sum_n mean_m(g_mn^2) |H_n(f_c)|^2 E_call / (M L)``
    per microphone, with E_call the call's energy and H_n the path response at the
    band centre.
    """

    snr_db: float = np.inf
    seed: int | None = 0
    reference: SnrReference = "signal"
    n_measurements: int | None = None


#: the default options and no noise (the defaults of the renderers' signatures)
DEFAULT_OPTIONS = RenderOptions()
NO_NOISE = Noise()
