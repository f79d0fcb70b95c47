"""Echoes: what every microphone receives, as a delay and a gain per path.

Every contribution of a scene (a point reflector, a specular path found by the ray
tracer, a scattering patch, the direct emitter-to-microphone path) becomes one
column of an :class:`Echoes`: its delay and its gain at each microphone, plus the
length of the path (for air absorption) and its order (0: direct path, 1: one
reflection, ...).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing import Array
from processing.errors import InputError

__all__ = ["Echoes", "PointReflectors", "point_echoes", "direct_path_echoes", "SPREADING"]

#: Spreading laws: ``paper`` is 1/(2 r_m) (eq. 1 of the paper, r_m the reflector to
#: microphone distance); ``spherical`` is 1/(r_e r_m), the physical law for a point
#: scatterer (r_e emitter to reflector), ``none`` leaves the strengths as given.
SPREADING = ("paper", "spherical", "none")


@dataclass(frozen=True, eq=False)
class Echoes:
    """Arrivals at each microphone.

    Attributes
    ----------
    delay_s : ndarray, shape (M, N)
        Arrival time of path n at microphone m, after the emission.
    gain : ndarray, shape (M, N)
        Amplitude factor (spreading, reflection, directivity), before air absorption.
    path_length_m : ndarray, shape (M, N)
        Total length travelled, for frequency-dependent air absorption.
    order : ndarray of int, shape (N,)
        Number of reflections of each path (0 for the direct path).
    emitter_angle_rad : ndarray, shape (N,), optional
        Angle between the emitter's axis and the direction the path leaves in (for
        emitter directivity); None when unknown (treated as on axis).
    interactions : ndarray of int, shape (N, K), optional
        Frequency-dependent material interactions of each path
        (:mod:`acousim.synth.materials`); None: none.
    """

    delay_s: np.ndarray
    gain: np.ndarray
    path_length_m: np.ndarray
    order: np.ndarray
    emitter_angle_rad: np.ndarray | None = None
    interactions: np.ndarray | None = None

    @property
    def n_paths(self) -> int:
        return self.delay_s.shape[1]

    def angles(self) -> np.ndarray:
        """Emitter angles (N,), zeros where unknown."""
        if self.emitter_angle_rad is None:
            return np.zeros(self.n_paths)
        return self.emitter_angle_rad

    def select(self, keep: np.ndarray) -> Echoes:
        """The echoes of the paths where `keep` (N,) is true."""
        return Echoes(
            self.delay_s[:, keep],
            self.gain[:, keep],
            self.path_length_m[:, keep],
            self.order[keep],
            self.angles()[keep],
            None if self.interactions is None else self.interactions[keep],
        )

    @staticmethod
    def empty(n_mics: int) -> Echoes:
        z = np.zeros((n_mics, 0))
        return Echoes(z, z, z, np.zeros(0, int))

    @staticmethod
    def concatenate(parts: list[Echoes]) -> Echoes:
        """Paths of several Echoes side by side (at least one part, same microphones)."""
        nonempty = [p for p in parts if p.n_paths]
        if not nonempty:
            return parts[0]
        parts = nonempty
        return Echoes(
            *(
                np.concatenate([getattr(p, f) for p in parts], axis=1)
                for f in ("delay_s", "gain", "path_length_m")
            ),
            np.concatenate([p.order for p in parts]),
            np.concatenate([p.angles() for p in parts]),
            _counts(parts),
        )


def _counts(parts: list[Echoes]) -> np.ndarray | None:
    """The interaction counts of several Echoes side by side (zeros where absent)."""
    if all(p.interactions is None for p in parts):
        return None
    k = max(p.interactions.shape[1] for p in parts if p.interactions is not None)
    return np.concatenate(
        [
            np.zeros((p.n_paths, k), int)
            if p.interactions is None
            else np.pad(p.interactions, ((0, 0), (0, k - p.interactions.shape[1])))
            for p in parts
        ]
    )


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
    """Echoes of point reflectors: emitter -> reflector -> microphone (eq. 1)."""
    if spreading not in SPREADING:
        raise ValueError(f"spreading must be one of {SPREADING}, got {spreading!r}")
    p = reflectors.positions_m
    r_e = np.linalg.norm(p - array.emitter_m, axis=1)  # (N,)
    r_m = np.linalg.norm(p[None, :, :] - array.positions_m[:, None, :], axis=2)  # (M, N)
    if np.any(r_e == 0) or np.any(r_m == 0):
        raise InputError(
            "a point reflector coincides with the emitter or a microphone",
            key="positions_m",
        )
    length = r_e[None, :] + r_m
    if spreading == "paper":
        gain = reflectors.strength / (2 * r_m)
    elif spreading == "spherical":
        gain = reflectors.strength / (r_e[None, :] * r_m)
    else:
        gain = np.broadcast_to(reflectors.strength, r_m.shape).copy()
    return Echoes(length / speed_of_sound_m_s, gain, length, np.ones(len(reflectors), int))


def direct_path_echoes(array: Array, speed_of_sound_m_s: float, gain: float = 1.0) -> Echoes:
    """The emitter-to-microphone crosstalk every real recording starts with (1/r)."""
    r = np.linalg.norm(array.positions_m - array.emitter_m, axis=1)[:, None]
    r = np.maximum(r, 1e-3)  # a microphone on the emitter: 1 mm, not a division by zero
    return Echoes(r / speed_of_sound_m_s, gain / r, r, np.zeros(1, int))
