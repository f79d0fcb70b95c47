"""Echoes of point reflectors (eq. 1) and of the direct emitter-to-microphone path,
as :class:`acousim.core.echoes.Echoes` (a delay and a gain per microphone and path).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.core.echoes import Echoes, spread
from processing import Array
from processing.base.errors import InputError

__all__ = ["Echoes", "PointReflectors", "point_echoes", "direct_path_echoes", "SPREADING"]

#: Spreading laws: ``paper`` is 1/(2 r_m) (eq. 1 of the paper, r_m the reflector to
#: microphone distance); ``spherical`` is 1/(r_e r_m), the physical law for a point
#: scatterer (r_e emitter to reflector), ``none`` leaves the strengths as given.
SPREADING = ("paper", "spherical", "none")


@dataclass(frozen=True, eq=False)
class PointReflectors:
    """Point reflectors of eq. 1: positions (N, 3) in metres, strengths a_k (N,)."""

    positions_m: np.ndarray
    strength: np.ndarray

    def __post_init__(self) -> None:
        pos = np.asarray(self.positions_m, float).reshape(-1, 3)
        a = np.broadcast_to(np.asarray(self.strength, float), (pos.shape[0],)).copy()
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(a))):
            raise ValueError("point reflectors: positions and strengths must be finite")
        object.__setattr__(self, "positions_m", pos)
        object.__setattr__(self, "strength", a)

    @classmethod
    def spherical(cls, azimuth_rad, elevation_rad, range_m, strength=1.0) -> PointReflectors:
        """Reflectors at (azimuth, elevation, range) from the origin."""
        az, el, r = (
            np.atleast_1d(np.asarray(v, float)) for v in (azimuth_rad, elevation_rad, range_m)
        )
        pos = r[:, None] * np.stack(
            [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1
        )
        return cls(pos, strength)

    def __len__(self) -> int:
        return self.positions_m.shape[0]


def point_echoes(
    reflectors: PointReflectors,
    array: Array,
    speed_of_sound_m_s: float,
    spreading: str = "spherical",
) -> Echoes:
    """Echoes of point reflectors: emitter -> reflector -> microphone (eq. 1); each
    reflector is the anchor of its path, its last leg spread as every path's
    (:func:`acousim.core.echoes.spread`), with the strength `spreading` gives it."""
    if spreading not in SPREADING:
        raise ValueError(f"spreading must be one of {SPREADING}, got {spreading!r}")
    p, a = reflectors.positions_m, reflectors.strength
    r_e = np.linalg.norm(p - array.emitter_m, axis=1)  # (N,)
    at_anchor = {"spherical": a / np.maximum(r_e, 1e-300), "paper": a / 2, "none": a}
    delay, gain, length = spread(
        p, r_e, at_anchor[spreading], array.positions_m, speed_of_sound_m_s
    )
    if np.any(r_e == 0) or np.any(length - r_e[None, :] <= 1e-6):
        raise InputError(
            "a point reflector coincides with the emitter or a microphone",
            key="positions_m",
        )
    if spreading == "none":  # the strengths as given: no spreading at all
        gain = np.broadcast_to(a, gain.shape).copy()
    return Echoes(delay, gain, length, np.ones(len(reflectors), int))


def direct_path_echoes(array: Array, speed_of_sound_m_s: float, gain: float = 1.0) -> Echoes:
    """The emitter-to-microphone crosstalk every real recording starts with (1/r)."""
    r = np.linalg.norm(array.positions_m - array.emitter_m, axis=1)[:, None]
    r = np.maximum(r, 1e-3)  # a microphone on the emitter: 1 mm, not a division by zero
    return Echoes(r / speed_of_sound_m_s, gain / r, r, np.zeros(1, int))
