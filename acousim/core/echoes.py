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

__all__ = ["Echoes"]


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
