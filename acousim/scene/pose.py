"""Sensor poses: position and orientation of the sensor frame in the world.

Both frames use x forward, y left, z up.  Orientation is yaw (about z, positive
turns left), pitch (about y, positive points the sensor down) and roll (about x):
``R = Rz(yaw) Ry(pitch) Rx(roll)`` maps sensor coordinates to world.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from processing.base.errors import InputError
from processing.base.frames import rotation  # the one sensor -> world rotation

__all__ = ["Pose", "rotation", "MAX_COORDINATE_M", "MAX_TIME_S"]

MAX_COORDINATE_M = 1e6
"""Largest coordinate (m, each axis) of anything in a scene: poses, points, mesh
vertices, tracks. 1000 km is beyond any sonar scene; checked when the scene is read,
so that no distance squared overflows (a warning before the error)."""

MAX_TIME_S = 1e7
"""Largest time (s) of a pose or a track row (115 days)."""


@dataclass(frozen=True, eq=False)
class Pose:
    """Where the sensor is: position (3,) in metres, yaw/pitch/roll in radians,
    and its time in a trajectory (seconds)."""

    position_m: np.ndarray
    yaw_rad: float = 0.0
    pitch_rad: float = 0.0
    roll_rad: float = 0.0
    time_s: float = 0.0

    def __post_init__(self) -> None:
        try:
            p = np.asarray(self.position_m, float).reshape(3)
        except (TypeError, ValueError):
            p = np.full(3, np.nan)
        if not np.all(np.isfinite(p)) or np.any(np.abs(p) > MAX_COORDINATE_M):
            raise InputError(
                f"must be 3 finite numbers within +-{MAX_COORDINATE_M:g} m",
                key="Pose.position_m",
                value=self.position_m,
            )
        object.__setattr__(self, "position_m", p)
        for name in ("yaw_rad", "pitch_rad", "roll_rad", "time_s"):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, int | float | np.number)
                or not np.isfinite(v)
                or abs(float(v)) > (MAX_TIME_S if name == "time_s" else 1e6)
            ):
                raise InputError("must be a finite number", key=f"Pose.{name}", value=v)
            object.__setattr__(self, name, float(v))

    @classmethod
    def degrees(
        cls,
        position_m,
        yaw_deg: float = 0.0,
        pitch_deg: float = 0.0,
        roll_deg: float = 0.0,
        *,
        time_s: float = 0.0,
    ) -> Pose:
        """A pose with its angles in degrees (what scene files and people type);
        ``Pose(position_m, yaw_rad, pitch_rad, roll_rad)`` takes radians."""
        for name, v in (("yaw_deg", yaw_deg), ("pitch_deg", pitch_deg), ("roll_deg", roll_deg)):
            if isinstance(v, bool) or not isinstance(v, int | float | np.number):
                raise InputError("must be a finite number", key=f"Pose.{name}", value=v)
        yaw, pitch, roll = np.deg2rad([yaw_deg, pitch_deg, roll_deg])
        return cls(position_m, float(yaw), float(pitch), float(roll), time_s)

    @property
    def rotation(self) -> np.ndarray:
        """Sensor -> world rotation (3, 3) (a copy of the one made once: the pose's
        angles do not change)."""
        return self._rotation.copy()

    @functools.cached_property
    def _rotation(self) -> np.ndarray:
        return rotation(self.yaw_rad, self.pitch_rad, self.roll_rad)

    def to_world(self, points_sensor: np.ndarray) -> np.ndarray:
        """Sensor-frame points (..., 3) to world coordinates."""
        return np.asarray(points_sensor) @ self.rotation.T + self.position_m

    def to_sensor(self, points_world: np.ndarray) -> np.ndarray:
        """World points (..., 3) to sensor coordinates."""
        return (np.asarray(points_world) - self.position_m) @ self.rotation

    def key(self) -> tuple:
        """A hashable identity (for not tracing the same pose twice)."""
        return (
            *np.round(self.position_m, 9),
            round(self.yaw_rad, 12),
            round(self.pitch_rad, 12),
            round(self.roll_rad, 12),
        )

    def to_dict(self) -> dict:
        return {
            "position_m": self.position_m.tolist(),
            "yaw_deg": float(np.rad2deg(self.yaw_rad)),
            "pitch_deg": float(np.rad2deg(self.pitch_rad)),
            "roll_deg": float(np.rad2deg(self.roll_rad)),
            "time_s": self.time_s,
        }
