"""One trial of the paper's study: simulate point reflectors, image, measure.

A trial is a pure function of its parameters, its seed and the study's `setup` (the
array, the methods, the sample rate and the steering frequency: any object with
those attributes, a :class:`acousim.experiments.StudyConfig`), so trials can run in
any order and in any process and give the same numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

import processing as P
from acousim.synth import Noise, PointReflectors, simulate_points

#: the paper's study: its methods, sample rate (Hz), array and steering frequency (Hz),
#: the defaults of :class:`acousim.experiments.StudyConfig`
PAPER_METHODS = ("das", "capon-fbss", "music", "music-fss", "music-fbss")
FS = 500e3
PAPER_ARRAY = "paper_8x8"
FREQUENCY_HZ = 31250.0  # the paper's steering frequency (below the 34.3 kHz alias limit)
C = 343.0
DURATION_S = 4096 / FS  # 8.2 ms: a reflector at 1 m and its 1 ms echo fit


class Setup(Protocol):
    """What a trial takes of the study's configuration."""

    array: str  # a name of processing.PRESETS
    methods: tuple[str, ...]
    sample_rate_hz: float
    frequency_hz: float


@dataclass(frozen=True)
class Paper:
    """The paper's setup (:class:`Setup`): the trials' default."""

    array: str = PAPER_ARRAY
    methods: tuple[str, ...] = PAPER_METHODS
    sample_rate_hz: float = FS
    frequency_hz: float = FREQUENCY_HZ


PAPER = Paper()


@dataclass(frozen=True)
class Trial:
    """Reflectors at (azimuth, elevation) in degrees and range in metres."""

    sources: tuple[tuple[float, float, float], ...]
    snr_db: float
    seed: int
    n_snapshots: int = 1


def local_grid(
    az_deg: float, el_deg: float, step: float, half_az: float = 45.0, half_el: float = 30.0
) -> P.Grid:
    """A grid around a direction, wide enough for DAS's -3 dB lobe at (60, 60)."""
    return P.Grid.degrees(
        (max(-90.0, az_deg - half_az), min(90.0, az_deg + half_az)),
        (max(-90.0, el_deg - half_el), min(90.0, el_deg + half_el)),
        step,
    )


def simulate_trial(trial: Trial, setup: Setup = PAPER) -> P.Recording:
    """The recording of `trial` by the array of `setup` at its sample rate: the paper's
    chirp, spreading 1/(2 r), 8.2 ms of samples."""
    az, el, r = (np.array(v, float) for v in zip(*trial.sources))
    refl = PointReflectors.spherical(np.deg2rad(az), np.deg2rad(el), r, 1.0)
    return simulate_points(
        refl,
        P.preset(setup.array),
        P.paper_chirp(),
        setup.sample_rate_hz,
        int(round(DURATION_S * setup.sample_rate_hz)),
        speed_of_sound_m_s=C,
        spreading="paper",
        noise=Noise(
            snr_db=trial.snr_db,
            seed=trial.seed,
            n_measurements=trial.n_snapshots if trial.n_snapshots > 1 else None,
        ),
    )


def images(
    trial: Trial, grid: P.Grid, setup: Setup = PAPER, methods: Sequence[str] | None = None
) -> dict[str, P.Image]:
    """The images of `trial` by `methods` (None: the setup's), steered at the setup's
    frequency, with the paper's gate (half the strongest bin's energy, all ranges) and
    subarrays of 5/8 of each dimension (5x5 on the paper's 8x8)."""
    settings = P.ProcessingSettings(
        frequency_hz=setup.frequency_hz,
        grid=grid,
        subarray=None,
        energy_fraction=0.5,
        range_limits_m=None,
    )
    chosen = setup.methods if methods is None else tuple(methods)
    return P.acoustic_images(simulate_trial(trial, setup), chosen, settings)


def resolution_trial(
    trial: Trial, step: float, setup: Setup = PAPER
) -> dict[str, tuple[float, float]]:
    """(angular resolution in sr, range resolution in m) per method of `setup`, on a
    grid of `step` degrees around the first source."""
    az, el, _ = trial.sources[0]
    out = {}
    for method, img in images(trial, local_grid(az, el, step), setup).items():
        if img.power.size == 0 or img.power.max() <= 0:
            out[method] = (np.nan, np.nan)
            continue
        out[method] = (P.angular_resolution(img), P.range_resolution(img))
    return out


def azimuth_cut_trial(
    trial: Trial, step: float, setup: Setup = PAPER, methods: Sequence[str] | None = None
) -> dict[str, np.ndarray]:
    """Spectra at elevation 0 summed over the kept range bins, per method of `methods`
    (None: the setup's): (A,), azimuth -90..90 every `step` degrees."""
    grid = P.Grid(np.deg2rad(np.arange(-90, 90 + step / 2, step)), np.array([0.0]))
    made = images(trial, grid, setup, methods)
    return {m: img.power[:, 0, :].sum(axis=0) for m, img in made.items()}
