"""Side lobes told from echoes (step 5 of :mod:`acousim.compare.comparison`): an
unmatched peak within one STFT window in range of a stronger peak of the same image is
that echo's side lobe (the window spreads one echo over the range bins it overlaps,
and the array's beam pattern puts lobes beside it in angle), reported with the
array's own response there (:func:`array_response_db`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

import processing as P
from acousim.compare.peaks import Peak

__all__ = ["SideLobe", "array_response_db", "side_lobes"]


@dataclass(frozen=True)
class SideLobe:
    """An unmatched peak within one STFT window in range of a stronger peak `of` of the
    same image: that echo's side lobe.  `array_response_db` is the array's narrow-band
    beam pattern (delay-and-sum, at the image's steering frequency) aimed at `of`,
    evaluated at this peak's direction: how strong a pure side lobe would be there."""

    peak: Peak
    of: Peak
    array_response_db: float

    def to_dict(self) -> dict:
        return {
            **asdict(self.peak),
            "of": asdict(self.of),
            "array_response_db": self.array_response_db,
        }


def _unit(az_deg: float, el_deg: float) -> np.ndarray:
    az, el = np.deg2rad(az_deg), np.deg2rad(el_deg)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def array_response_db(
    array: P.Array, frequency_hz: float, c: float, towards: Peak, at: Peak
) -> float:
    """Narrow-band delay-and-sum beam pattern aimed at `towards`, at `at`'s direction,
    in dB re its maximum: |a(at)^H a(towards)|^2 / M^2."""
    k = 2 * np.pi * frequency_hz / c
    pos = array.positions_m
    a0 = np.exp(1j * k * pos @ _unit(towards.azimuth_deg, towards.elevation_deg))
    a1 = np.exp(1j * k * pos @ _unit(at.azimuth_deg, at.elevation_deg))
    r = abs(np.vdot(a1, a0)) ** 2 / len(pos) ** 2
    return float(10 * np.log10(max(r, 1e-30)))


def side_lobes(
    peaks: Sequence[Peak],
    candidates: Sequence[int],
    extent_m: float,
    array: P.Array,
    frequency_hz: float,
    c: float,
) -> tuple[list[SideLobe], list[int]]:
    """Split `candidates` (indices into `peaks`, strongest first) into side lobes of a
    stronger peak within `extent_m` in range, and the rest."""
    lobes, rest = [], []
    for i in candidates:
        p = peaks[i]
        parents = [
            q for q in peaks if q.level_db > p.level_db and abs(q.range_m - p.range_m) <= extent_m
        ]
        if parents:
            top = max(parents, key=lambda q: q.level_db)
            lobes.append(SideLobe(p, top, array_response_db(array, frequency_hz, c, top, p)))
        else:
            rest.append(i)
    return lobes, rest
