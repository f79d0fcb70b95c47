"""One trial of the paper's study: simulate point reflectors, image, measure.

A trial is a pure function of its parameters and seed, so trials can run in any
order and in any process and give the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import processing as P
from acousim.synth import Noise, PointReflectors, simulate_points

PAPER_METHODS = ("das", "capon-fbss", "music", "music-fss", "music-fbss")
FS = 500e3
C = 343.0
N_SAMPLES = 4096  # 8.2 ms: a reflector at 1 m and its 1 ms echo fit
FREQUENCY_HZ = 31250.0  # the paper's steering frequency (below the 34.3 kHz alias limit)


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


def simulate_trial(trial: Trial) -> P.Recording:
    az, el, r = (np.array(v, float) for v in zip(*trial.sources))
    refl = PointReflectors.spherical(np.deg2rad(az), np.deg2rad(el), r, 1.0)
    return simulate_points(
        refl,
        P.paper_8x8(),
        P.paper_chirp(),
        FS,
        N_SAMPLES,
        speed_of_sound_m_s=C,
        spreading="paper",
        noise=Noise(
            snr_db=trial.snr_db,
            seed=trial.seed,
            n_measurements=trial.n_snapshots if trial.n_snapshots > 1 else None,
        ),
    )


def images(trial: Trial, grid: P.Grid, methods=PAPER_METHODS) -> dict[str, P.Image]:
    settings = P.ProcessingSettings(  # the paper's gate, all ranges
        frequency_hz=FREQUENCY_HZ,
        grid=grid,
        subarray=(5, 5),
        energy_fraction=0.5,
        range_limits_m=None,
    )
    return P.acoustic_images(simulate_trial(trial), methods, settings)


def resolution_trial(trial: Trial, step: float) -> dict[str, tuple[float, float]]:
    """(angular resolution in sr, range resolution in m) per method."""
    az, el, _ = trial.sources[0]
    out = {}
    for method, img in images(trial, local_grid(az, el, step)).items():
        if img.power.size == 0 or img.power.max() <= 0:
            out[method] = (np.nan, np.nan)
            continue
        out[method] = (P.angular_resolution(img), P.range_resolution(img))
    return out


def azimuth_cut_trial(trial: Trial, step: float) -> dict[str, np.ndarray]:
    """Spectra at elevation 0 summed over the kept range bins, per method: (A,)."""
    grid = P.Grid(np.deg2rad(np.arange(-90, 90 + step / 2, step)), np.array([0.0]))
    return {m: img.power[:, 0, :].sum(axis=0) for m, img in images(trial, grid).items()}
