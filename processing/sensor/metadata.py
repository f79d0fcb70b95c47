"""The metadata of a recording (a JSON object): the keys the programs read, checked
one by one when a file is read and before one is written (the typed reading of
them is :class:`processing.sensor.provenance.Provenance`).

Keys (others are free, see docs/recording-format.md): ``pose`` (position_m required;
yaw_deg, pitch_deg, roll_deg, time_s, 0 when absent), ``motion`` (velocity_m_s,
angular_velocity_deg_s, emission_pose, doppler_min, doppler_max), ``scene``,
``scene_file``, ``simulated``, ``pose_index``, ``n_paths``, ``max_range_m``,
``timestamp``.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["metadata_problem", "MAX_POSE_COORDINATE_M", "MAX_TIME_S"]

MAX_POSE_COORDINATE_M = 1e6
"""The largest |coordinate| (m) of a pose in a file (acousim.scene's bound)."""
MAX_TIME_S = 2e9
"""The largest |time| (s) of a pose or a timestamp in a file (a ROS stamp's int32
seconds, year 2033)."""

_POSE_DEFAULTS = {"yaw_deg": 0.0, "pitch_deg": 0.0, "roll_deg": 0.0, "time_s": 0.0}
_POSE_FORM = (
    "{position_m: [x, y, z][, yaw_deg, pitch_deg, roll_deg, time_s]} with finite numbers "
    f"(positions within +-{MAX_POSE_COORDINATE_M:g} m, times within +-{MAX_TIME_S:g} s)"
)


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _whole(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


def _vector(v, bound: float = math.inf) -> bool:
    return isinstance(v, list) and len(v) == 3 and all(_number(x) and abs(x) <= bound for x in v)


def _pose_ok(pose) -> bool:
    return (
        isinstance(pose, dict)
        and _vector(pose.get("position_m"), MAX_POSE_COORDINATE_M)
        and all(_number(pose.get(k, d)) for k, d in _POSE_DEFAULTS.items())
        and abs(pose.get("time_s", 0.0)) <= MAX_TIME_S
    )


def _motion_ok(m) -> bool:
    if not isinstance(m, dict):
        return False
    vectors = all(_vector(m[k]) for k in ("velocity_m_s", "angular_velocity_deg_s") if k in m)
    numbers = all(_number(m[k]) and m[k] > 0 for k in ("doppler_min", "doppler_max") if k in m)
    pose = "emission_pose" not in m or _pose_ok(m["emission_pose"])
    return vectors and numbers and pose


_CHECKS = {
    "pose": (_pose_ok, _POSE_FORM),
    "scene": (lambda v: isinstance(v, str), "a string"),
    "scene_file": (lambda v: v is None or isinstance(v, str), "a string or null"),
    "simulated": (lambda v: isinstance(v, bool), "true or false"),
    "pose_index": (_whole, "a whole number >= 0"),
    "n_paths": (_whole, "a whole number >= 0"),
    "max_range_m": (lambda v: _number(v) and v > 0, "a positive number"),
    "timestamp": (
        lambda v: v is None or (_number(v) and abs(v) <= MAX_TIME_S),
        f"a number within +-{MAX_TIME_S:g} s or null",
    ),
    "motion": (
        _motion_ok,
        "{velocity_m_s: [3 numbers], angular_velocity_deg_s: [3 numbers], "
        "emission_pose: a pose, doppler_min, doppler_max (positive)}",
    ),
}


def metadata_problem(meta: Any) -> tuple[str, str, Any] | None:
    """None when `meta` (parsed JSON) is a valid metadata object, else ``(where, what
    it must be, the value)`` for the first bad key (`where` ``": pose"``, or ``""``
    for the whole object)."""
    if not isinstance(meta, dict):
        return "", "must be a JSON object", meta
    for name, (ok, form) in _CHECKS.items():
        if name in meta and not ok(meta[name]):
            return f": {name}", f"must be {form}", meta[name]
    return None
