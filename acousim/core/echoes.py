"""Echoes: what every microphone receives, as a delay and a gain per path.

Every contribution of a scene (a point reflector, a specular path found by the ray
tracer, a scattering patch, the direct emitter-to-microphone path) becomes one
column of an :class:`Echoes`: its delay and its gain at each microphone, plus the
length of the path (for air absorption) and its order (0: direct path, 1: one
reflection, ...).  The kinematics stage makes them, the renderer (:mod:`acousim.synth`)
turns them into signals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Echoes", "last_legs", "spread"]


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
        (:mod:`acousim.core.materials`); None: none.
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


def last_legs(anchor_m: np.ndarray, mics_m: np.ndarray) -> np.ndarray:
    """(M, N) the distances from anchors (N, 3) to microphones (M, 3), m (at least
    1 µm)."""
    # |anchor - mic| per coordinate: the same sums as a norm over a (M, N, 3) array,
    # without it (8x faster)
    a, p = anchor_m.T, mics_m[:, :, None]
    last = np.square(a[0] - p[:, 0])
    last += np.square(a[1] - p[:, 1])
    last += np.square(a[2] - p[:, 2])
    return np.maximum(np.sqrt(last, out=last), 1e-6)


def spread(
    anchor_m: np.ndarray,
    first_leg_m: np.ndarray,
    strength: np.ndarray,
    mics_m: np.ndarray,
    speed_of_sound_m_s: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The spherical spreading of the last leg, the one law of every path: a path of
    length `first_leg_m` (N,) up to its anchor `anchor_m` (N, 3), where its pressure
    at 1 m is `strength` (N,), heard at microphones `mics_m` (M, 3) (one frame, m):

    1. the last leg r_mn = |anchor_n - mic_m| (at least 1 µm);
    2. the path's length L = first leg + r_mn, its delay L / c;
    3. its gain strength_n / r_mn.

    Returns delays (M, N) s, gains (M, N), lengths (M, N) m.  A point reflector of
    strength a at distance r_e from the emitter is the anchor of strength a / r_e:
    gain a / (r_e r_m).
    """
    last = last_legs(anchor_m, mics_m)
    length = first_leg_m[None, :] + last
    return length / speed_of_sound_m_s, strength[None, :] / last, length


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
