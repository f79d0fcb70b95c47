"""A spinning LiDAR beside the sonar: its settings, declared once, and two presets.

The scene file's ``[sensor.lidar]`` table (``docs/scene-format.md``) starts from a
``preset`` (default ``"vlp16"``) and overrides any of the settings of :class:`Lidar`;
in Python, ``lidar_preset("hdl32e", range_m=(0.5, 30.0))``. The scan itself is
:func:`acousim.trace.lidar.scan`.

Presets (the makers' data sheets; the minimum range is our choice, the sheets give
none): Velodyne VLP-16 ("Puck"): 16 channels from -15 to +15 degrees (2 degrees
apart), 0.2 degrees horizontal resolution at 10 rotations per second, up to 100 m,
+-3 cm typical accuracy. Velodyne HDL-32E: 32 channels from -30.67 to +10.67 degrees
(1.33 degrees apart), 0.16 degrees at 10 Hz, up to 100 m, +-2 cm.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from acousim.scene.pose import rotation
from processing.base.settings import Setting, check, setting, validate

__all__ = ["Lidar", "LidarPreset", "LIDAR_PRESETS", "PRESET", "lidar_preset"]

LidarPreset = Literal["vlp16", "hdl32e"]
#: the scene file's ``[sensor.lidar] preset``, checked in one place
PRESET = Setting("str", "vlp16", doc="the unit the other settings start from",
                 choices=get_args(LidarPreset))  # fmt: skip


@dataclass(frozen=True)
class Lidar:
    """A spinning multi-channel LiDAR mounted on the sonar (defaults: a VLP-16).

    Beams: `channels` elevations evenly spaced over `elevation_deg` (both ends
    included), azimuths every `azimuth_step_deg` over `azimuth_deg`, swept clockwise
    seen from above (from the high end down) at `rate_hz` turns per second, so the
    beam at azimuth a fires ``(a_high - a) / 360 / rate_hz`` after the scan starts.
    A point is reported in the LiDAR frame where that beam meets the first surface
    between the two ends of `range_m`; the mounting (`position_m`, `rotation_deg` as
    roll, pitch, yaw about x, y, z, like a mesh's) places the LiDAR frame in the
    sonar's.
    """

    name: str = setting("VLP-16", doc="the unit's name, written to files")
    channels: int = setting(16, "", 1, 256, "vertical channels (beams)")
    elevation_deg: tuple[float, float] = setting(
        (-15.0, 15.0), "deg", -90, 90, "lowest and highest beam", kind="interval"
    )
    azimuth_deg: tuple[float, float] = setting(
        (-180.0, 180.0), "deg", -180, 180, "horizontal field of view", kind="interval"
    )
    azimuth_step_deg: float = setting(0.2, "deg", 0.01, 45, "horizontal resolution")
    range_m: tuple[float, float] = setting(
        (0.1, 100.0), "m", 0, 1000, "nearest and farthest return", kind="interval"
    )
    rate_hz: float = setting(10.0, "Hz", 0.1, 100, "rotations per second")
    position_m: tuple[float, float, float] = setting(
        (0.0, 0.0, 0.0), "m", -10, 10, "mounting: position in the sonar frame", length=3
    )
    rotation_deg: tuple[float, float, float] = setting(
        (0.0, 0.0, 0.0), "deg", -360, 360, "mounting: roll, pitch, yaw", length=3
    )
    range_noise_m: float = setting(0.0, "m", 0, 1, "Gaussian range noise (std); 0: exact")

    def __post_init__(self) -> None:
        validate(self)

    def elevations_rad(self) -> np.ndarray:
        """Beam elevations (C,), lowest first (channel 0)."""
        lo, hi = np.deg2rad(self.elevation_deg)
        return np.linspace(lo, hi, self.channels) if self.channels > 1 else np.array([lo])

    def azimuths_rad(self) -> np.ndarray:
        """Firing azimuths (A,) in firing order (clockwise: decreasing); a full turn
        does not fire its first azimuth twice."""
        lo, hi = self.azimuth_deg
        n = int(np.floor((hi - lo) / self.azimuth_step_deg + 1e-9))
        full = hi - lo >= 360 - 1e-9
        return np.deg2rad(hi - self.azimuth_step_deg * np.arange(n if full else n + 1))

    def firing_times_s(self) -> np.ndarray:
        """Time of each azimuth's firing after the start of the scan (A,)."""
        return (np.deg2rad(self.azimuth_deg[1]) - self.azimuths_rad()) / (2 * np.pi) / self.rate_hz

    def to_sensor(self) -> np.ndarray:
        """The mounting: 4x4 LiDAR frame -> sonar frame."""

        roll, pitch, yaw = np.deg2rad(self.rotation_deg)
        T = np.eye(4)
        T[:3, :3] = rotation(yaw, pitch, roll)
        T[:3, 3] = self.position_m
        return T


LIDAR_PRESETS: dict[str, Lidar] = {
    "vlp16": Lidar(),
    "hdl32e": Lidar(
        name="HDL-32E",
        channels=32,
        elevation_deg=(-30.67, 10.67),
        azimuth_step_deg=0.16,
        range_m=(0.1, 100.0),
    ),
}


def lidar_preset(name: str = "vlp16", **overrides) -> Lidar:
    """A preset (:data:`LIDAR_PRESETS`) with some settings changed."""

    return dataclasses.replace(LIDAR_PRESETS[check(PRESET, name, "lidar preset")], **overrides)
