"""Motion of a scene's items: the speed limits, the velocity setting, tracks (a
point's or a mesh's own trajectory) checked and evaluated.  Below
:mod:`acousim.scene.model` and :mod:`acousim.scene.trajectory`, which both use it."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from acousim.scene.pose import MAX_COORDINATE_M, MAX_TIME_S
from processing.base.errors import InputError
from processing.base.settings import setting

__all__ = ["MAX_SPEED_M_S", "MAX_TURN_DEG_S", "track_rows", "velocity_setting"]

MAX_SPEED_M_S = 100.0
"""Fastest motion of the sensor or a reflector (m/s, each velocity component; well
below the speed of sound, which the retarded-time solution needs)."""
MAX_TURN_DEG_S = 3600.0
"""Fastest turn of the sensor (degrees/s about each world axis)."""


def velocity_setting():
    """The velocity of a moving point or mesh, declared once for both."""
    return setting(
        (0.0, 0.0, 0.0),
        "m/s",
        -MAX_SPEED_M_S,
        MAX_SPEED_M_S,
        "velocity (world frame) from position_m at time 0",
        kind="vector",
        length=3,
    )


def vector3(value: Any, key: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = np.full(0, np.nan)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(np.abs(v) > MAX_COORDINATE_M):
        raise InputError(
            f"must be 3 finite numbers within +-{MAX_COORDINATE_M:g} m", key=key, value=value
        )
    return v


def moves(item) -> bool:
    """Whether a point or a mesh has a track or a non-zero velocity."""
    return item.track is not None or any(v != 0 for v in item.velocity_m_s)


def motion_at(item, start_m, t_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity (3,) at `t_s` of an item (point or mesh) with a
    ``velocity_m_s`` and a ``track``, at `start_m` at time 0 without a track."""
    if item.track is None:
        v = np.asarray(item.velocity_m_s, float)
        return np.asarray(start_m, float) + v * t_s, v
    from scipy.interpolate import CubicSpline

    rows = np.asarray(item.track, float)
    spline = CubicSpline(rows[:, 0], rows[:, 1:4], bc_type="natural")
    return spline(t_s), spline(t_s, 1)


def _track_rotations(rows: np.ndarray):
    """The rotations (scipy Rotation, one per row) of a track's roll, pitch, yaw
    columns (rad), each ``Rz(yaw) Ry(pitch) Rx(roll)`` as a pose's."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("ZYX", rows[:, [6, 5, 4]])


def track_rotation(track, t_s: float):
    """A turning track's orientation at `t_s` (a scipy Rotation) and its angular
    velocity (3,) in the mesh's own frame: a rotation spline through the rows (a
    constant turn rate between equally spaced rows is kept exactly); before the
    first row and after the last, turning on at the end's rate."""
    from scipy.spatial.transform import Rotation, RotationSpline

    rows = np.asarray(track, float)
    spline = RotationSpline(rows[:, 0], _track_rotations(rows))
    t = float(np.clip(t_s, rows[0, 0], rows[-1, 0]))
    turn, rate = spline(t), spline(t, 1)
    if t != t_s:  # beyond an end: on at the end's rate (body frame)
        turn = turn * Rotation.from_rotvec(rate * (t_s - t))
    return turn, rate


def track_rows(value: Any, key: str, turns: bool = False) -> tuple[tuple[float, ...], ...]:
    """A track checked: two or more rows [t_s, x, y, z] of finite numbers
    (positions in m, speeds between rows up to MAX_SPEED_M_S), times increasing;
    with `turns` (a mesh's), rows [t_s, x, y, z, roll, pitch, yaw] (rad) may give
    its orientation too (turning between rows up to MAX_TURN_DEG_S)."""
    try:
        ok = not isinstance(value, str | bytes) and all(
            not isinstance(x, bool | str | bytes) for row in value for x in row
        )
        arr = np.array(value, float) if ok else np.zeros((0, 0))
    except (ValueError, TypeError):
        arr = np.zeros((0, 0))
    widths = (4, 7) if turns else (4,)
    if (
        arr.ndim != 2
        or arr.shape[0] < 2
        or arr.shape[1] not in widths
        or not np.all(np.isfinite(arr))
        or np.any(np.abs(arr[:, 1:4]) > MAX_COORDINATE_M)
        or np.any(np.abs(arr[:, 0]) > MAX_TIME_S)
    ):
        form = "[t_s, x, y, z] or [t_s, x, y, z, roll, pitch, yaw]" if turns else "[t_s, x, y, z]"
        raise InputError(
            f"must be two or more rows {form} of finite numbers (|t_s| <= {MAX_TIME_S:g}, "
            f"positions within +-{MAX_COORDINATE_M:g} m)",
            key=key,
            value=value,
        )
    dt = np.diff(arr[:, 0])
    if not np.all(dt > 0):
        raise InputError("times must increase", key=key, value=arr[:, 0].tolist())
    speed = np.linalg.norm(np.diff(arr[:, 1:4], axis=0), axis=1) / dt
    if np.any(speed > MAX_SPEED_M_S):
        raise InputError(
            f"moves faster than {MAX_SPEED_M_S:g} m/s between rows", key=key, value=value
        )
    if arr.shape[1] == 7:
        rot = _track_rotations(arr)
        rate = (rot[:-1].inv() * rot[1:]).magnitude() / dt
        if np.any(rate > math.radians(MAX_TURN_DEG_S)):
            raise InputError(
                f"turns faster than {MAX_TURN_DEG_S:g} deg/s between rows", key=key, value=value
            )
    return tuple(tuple(float(v) for v in row) for row in arr)
