"""How far apart the two aligned recordings' levels are (steps 2 and 3 of
:mod:`acousim.compare.comparison`): per channel, the correlation of the matched-filter
envelopes; along range, the range profiles (mean envelope power over the microphones
per range bin) and their ratio in dB."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RangeProfiles", "envelope_correlation", "range_profiles"]


def envelope_correlation(env_r: np.ndarray, env_s: np.ndarray) -> tuple[float, ...]:
    """Per channel, the correlation coefficient of the real and simulated envelopes
    (M, T) (0 where either is constant)."""
    return tuple(
        float(np.corrcoef(er, es)[0, 1]) if er.std() > 0 and es.std() > 0 else 0.0
        for er, es in zip(env_r, env_s)
    )


@dataclass(frozen=True, eq=False)
class RangeProfiles:
    """Range-bin edges (B + 1,) in m, the real and simulated range profiles (B,)
    (envelope power, mean over the microphones, summed per bin) and
    10 log10(real / simulated) per bin (B,)."""

    edges_m: np.ndarray
    real: np.ndarray
    sim: np.ndarray
    level_difference_db: np.ndarray


def range_profiles(
    range_m: np.ndarray, env_r: np.ndarray, env_s: np.ndarray, range_bin_m: float
) -> RangeProfiles:
    """Energy of the envelopes (M, T) per range bin of `range_bin_m` (m) over the
    ranges `range_m` (T,) of their samples."""
    edges = np.arange(0, range_m[-1] + range_bin_m, range_bin_m)
    idx = np.clip(np.digitize(range_m, edges) - 1, 0, len(edges) - 2)
    prof_r = np.bincount(idx, (env_r**2).mean(axis=0), len(edges) - 1)
    prof_s = np.bincount(idx, (env_s**2).mean(axis=0), len(edges) - 1)
    tiny = 1e-30
    return RangeProfiles(edges, prof_r, prof_s, 10 * np.log10((prof_r + tiny) / (prof_s + tiny)))
