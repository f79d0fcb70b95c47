"""One trial of the paper's study: simulate point reflectors, image, measure.

A trial is a pure function of its parameters, its seed and the study's `setup` (the
array, the methods, the sample rate and the steering frequency: any object with
those attributes, a :class:`acousim.experiments.StudyConfig`), so trials can run in
any order and in any process and give the same numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
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
    chosen = setup.methods if methods is None else tuple(methods)
    return P.acoustic_images(simulate_trial(trial, setup), chosen, _settings(grid, setup))


def _settings(grid: P.Grid, setup: Setup) -> P.ProcessingSettings:
    """The trials' imaging settings on `grid` (:func:`images`)."""
    return P.ProcessingSettings(
        frequency_hz=setup.frequency_hz,
        grid=grid,
        subarray=None,
        energy_fraction=0.5,
        range_limits_m=None,
    )


def resolution_trial(
    trial: Trial, step: float, setup: Setup = PAPER
) -> dict[str, tuple[float, float, float]]:
    """(angular resolution in sr, range resolution in m, 1.0 when the -3 dB lobe was
    narrower than a grid step else 0.0) per method of `setup`, on a grid of `step`
    degrees around the first source; NaNs when the image is empty.

    A lobe narrower than one step of the grid is measured again on a fine grid
    around it (:func:`processing.imaging.metrics.solid_angle_detail` with the
    trial's spectrum by the same setup and method on that range slice), so the
    value does not rest on the grid."""
    az, el, _ = trial.sources[0]
    out = {}
    for method, img in images(trial, local_grid(az, el, step), setup).items():
        if img.power.size == 0 or img.power.max() <= 0:
            out[method] = (np.nan, np.nan, np.nan)
            continue
        angular = P.angular_resolution_detail(img)
        if angular.sub_cell:
            r = int(np.unravel_index(int(np.argmax(img.power)), img.power.shape)[0])
            spectrum = _slice_spectrum(trial, method, float(img.range_m[r]), setup)
            angular = P.angular_resolution_detail(img, spectrum=spectrum)
            sub_cell = 1.0
        else:
            sub_cell = 0.0
        out[method] = (angular.solid_angle_sr, P.range_resolution(img), sub_cell)
    return out


def _slice_spectrum(trial: Trial, method: str, range_m: float, setup: Setup):
    """``spectrum(elevation_rad (E,), azimuth_rad (A,)) -> power (E, A)``: the
    trial's `method` image by `setup` on those directions, at its range bin nearest
    `range_m`.  The trial is simulated and its snapshot made (gated over all its
    bins, as by :func:`images`) once; each call images that one bin."""
    rec = simulate_trial(trial, setup)
    settings = _settings(P.Grid(np.zeros(1), np.zeros(1)), setup)
    snap = P.recording_snapshot(rec, settings)
    r = int(np.argmin(np.abs(snap.range_m - range_m)))
    one_bin = replace(
        snap,
        data=snap.data[:, r : r + 1],
        range_m=snap.range_m[r : r + 1],
        time_s=snap.time_s[r : r + 1],
        energy=snap.energy[r : r + 1],
    )

    def spectrum(elevation_rad: np.ndarray, azimuth_rad: np.ndarray) -> np.ndarray:
        grid = P.Grid(azimuth_rad, elevation_rad)
        made = P.acoustic_images(rec, (method,), replace(settings, grid=grid), snapshot=one_bin)
        return made[method].power[0]

    return spectrum


def azimuth_cut_trial(
    trial: Trial, step: float, setup: Setup = PAPER, methods: Sequence[str] | None = None
) -> dict[str, np.ndarray]:
    """Spectra at elevation 0 summed over the kept range bins, per method of `methods`
    (None: the setup's): (A,), azimuth -90..90 every `step` degrees."""
    grid = P.Grid(np.deg2rad(np.arange(-90, 90 + step / 2, step)), np.array([0.0]))
    made = images(trial, grid, setup, methods)
    return {m: img.power[:, 0, :].sum(axis=0) for m, img in made.items()}


def strongest_bin_frequency_hz(setup: Setup = PAPER) -> float:
    """The frequency (Hz) the imaging pipeline's own rule (``frequency_hz=None``: the
    strongest STFT bin of the call's band below the array's alias-free limit) picks
    for the study's chirp, noise-free echo from (0, 0, 1 m), by `setup`'s array at
    its sample rate."""
    rec = simulate_trial(Trial(((0.0, 0.0, 1.0),), np.inf, 0), setup)
    settings = P.ProcessingSettings(
        frequency_hz=None,
        grid=P.Grid(np.zeros(1), np.zeros(1)),
        subarray=None,
        energy_fraction=0.5,
        range_limits_m=None,
    )
    return float(P.acoustic_images(rec, ("das",), settings)["das"].frequency_hz)


def das_beamwidth_deg(
    frequency_hz: float = FREQUENCY_HZ, step_deg: float = 0.01, setup: Setup = PAPER
) -> float:
    """-3 dB width (degrees) in azimuth at elevation 0 of the study's DAS image of a
    noise-free reflector at (0, 0, 1 m) by `setup`'s array at its sample rate, steered
    at `frequency_hz`, on the kept range bin of its maximum (linear interpolation
    between the cut's samples)."""
    grid = P.Grid(np.deg2rad(np.arange(-30, 30 + step_deg / 2, step_deg)), np.zeros(1))
    settings = P.ProcessingSettings(
        frequency_hz=frequency_hz,
        grid=grid,
        subarray=None,
        energy_fraction=0.5,
        range_limits_m=None,
    )
    img = P.acoustic_images(
        simulate_trial(Trial(((0.0, 0.0, 1.0),), np.inf, 0), setup), ("das",), settings
    )
    power = img["das"].power
    cut = power[int(np.argmax(power.max(axis=(1, 2)))), 0]
    az = np.rad2deg(grid.azimuth_rad)
    i = int(np.argmax(cut))
    half = cut[i] * 10 ** (-0.3)
    right = i + int(np.argmax(cut[i:] < half))
    left = i - int(np.argmax(cut[: i + 1][::-1] < half))

    def cross(j, k):  # between samples j (inside) and k (outside)
        return az[j] + (cut[j] - half) / (cut[j] - cut[k]) * (az[k] - az[j])

    return float(cross(right - 1, right) - cross(left + 1, left))
