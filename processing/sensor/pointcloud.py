"""A LiDAR scan taken with a recording: the points, and how they sit on the sonar.

A :class:`PointCloud` rides on a :class:`processing.Recording` (``rec.lidar``): the
scan taken at the recording's pose (simulated: ``acousim.trace.lidar``; read from a
CHIRP file: its ``lidar_00`` sensor).  Points are in the LiDAR's own frame (x forward,
y left, z up, like the sonar's); ``to_sensor`` maps them into the sonar's frame
(the array's: ``p_sonar = to_sensor @ [x, y, z, 1]``).

In a recording file a scan is the group ``lidar/`` of its recording (see
``docs/recording-format.md``)::

    lidar/points_m        (P, 3) float32, units "m", LiDAR frame
    lidar/intensity       (P,) float32, units "1", 0..1
    lidar/ring            (P,) int16, channel of each point (0: the lowest beam)
    lidar/time_s          (P,) float32, units "s", firing time after the scan start
    lidar/to_sensor       (4, 4) float64: LiDAR frame -> sonar frame
    attrs: name, rate_hz
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from processing.base.errors import InputError

__all__ = ["PointCloud", "write_point_cloud", "read_point_cloud"]


@dataclass(frozen=True, eq=False)
class PointCloud:
    """One LiDAR scan (P points).

    Attributes
    ----------
    points_m : ndarray, shape (P, 3)
        Points in the LiDAR frame (m).
    intensity : ndarray, shape (P,)
        Return strength, 0..1 (simulated: the cosine of the incidence angle).
    to_sensor : ndarray, shape (4, 4)
        Rigid transform LiDAR frame -> sonar (array) frame.
    ring : ndarray of int, shape (P,), or None
        The vertical channel of each point (0: the lowest beam); None when unknown.
    time_s : ndarray, shape (P,), or None
        Firing time of each point after the start of the scan (s); None when unknown.
    name : str
        The unit (``"VLP-16"``, ``"HDL-32E"``, or what a file calls it).
    rate_hz : float
        Rotations per second (a scan lasts 1 / rate_hz); NaN when unknown.
    """

    points_m: np.ndarray
    intensity: np.ndarray
    to_sensor: np.ndarray
    ring: np.ndarray | None = None
    time_s: np.ndarray | None = None
    name: str = "lidar"
    rate_hz: float = float("nan")

    def __post_init__(self) -> None:
        p = np.asarray(self.points_m, float).reshape(-1, 3)
        n = len(p)
        inten = np.asarray(self.intensity, float).reshape(-1)
        T = np.asarray(self.to_sensor, float)
        if len(inten) != n:
            raise ValueError(f"point cloud: {len(inten)} intensities for {n} points")
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(inten))):
            raise ValueError("point cloud: points and intensities must be finite")
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"point cloud: to_sensor must be a finite 4x4 matrix, got {T.shape}")
        R = T[:3, :3]
        if not (np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.allclose(T[3], [0, 0, 0, 1])):
            raise ValueError("point cloud: to_sensor must be a rigid transform (rotation, shift)")
        object.__setattr__(self, "points_m", p)
        object.__setattr__(self, "intensity", inten)
        object.__setattr__(self, "to_sensor", T)
        for name, kind in (("ring", int), ("time_s", float)):
            v = getattr(self, name)
            if v is not None:
                v = np.asarray(v, kind).reshape(-1)
                if len(v) != n:
                    raise ValueError(f"point cloud: {len(v)} {name} values for {n} points")
                object.__setattr__(self, name, v)
        object.__setattr__(self, "rate_hz", float(self.rate_hz))

    def __len__(self) -> int:
        return len(self.points_m)

    def __repr__(self) -> str:
        return f"PointCloud({self.name!r}, {len(self)} points)"

    def in_sensor(self) -> np.ndarray:
        """The points in the sonar's frame, shape (P, 3) (m)."""
        return self.points_m @ self.to_sensor[:3, :3].T + self.to_sensor[:3, 3]

    def range_m(self) -> np.ndarray:
        """Distance of each point from the LiDAR, shape (P,) (m)."""
        return np.linalg.norm(self.points_m, axis=1)


def write_point_cloud(g: h5py.Group, pc: PointCloud, checksum: bool = True) -> None:
    """Write `pc` into the (empty) group `g` (layout in the module docstring)."""
    kw = {"fletcher32": checksum} if len(pc) else {}
    for name, data, units in (
        ("points_m", pc.points_m.astype(np.float32), "m"),
        ("intensity", pc.intensity.astype(np.float32), "1"),
        ("ring", None if pc.ring is None else pc.ring.astype(np.int16), None),
        ("time_s", None if pc.time_s is None else pc.time_s.astype(np.float32), "s"),
    ):
        if data is not None:
            d = g.create_dataset(name, data=data, **kw)
            if units:
                d.attrs["units"] = units
    g.create_dataset("to_sensor", data=pc.to_sensor)
    g.attrs["name"] = pc.name
    g.attrs["rate_hz"] = pc.rate_hz


def read_point_cloud(
    path: str | Path, g: h5py.Group, error: type[InputError] = InputError
) -> PointCloud:
    """The scan in group `g` of file `path`; an `error` (an InputError) names the file
    and the field."""

    def get(name: str, ndim: int, kinds: str, required: bool = True):
        key = f"{g.name}/{name}"
        if name not in g:
            if required:
                raise error("missing", file=path, key=key)
            return None
        d = g[name]
        if not isinstance(d, h5py.Dataset) or d.ndim != ndim or d.dtype.kind not in kinds:
            raise error(f"must be a {ndim}-D numeric dataset", file=path, key=key)
        try:
            return d[()]
        except OSError as exc:
            raise error(f"cannot be read ({exc})", file=path, key=key) from None

    try:
        return PointCloud(
            points_m=get("points_m", 2, "f"),
            intensity=get("intensity", 1, "f"),
            to_sensor=get("to_sensor", 2, "f"),
            ring=get("ring", 1, "iu", False),
            time_s=get("time_s", 1, "f", False),
            name=str(g.attrs.get("name", "lidar")),
            rate_hz=float(g.attrs.get("rate_hz", float("nan"))),
        )
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        raise error(str(exc), file=path, key=g.name) from None
