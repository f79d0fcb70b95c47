"""Where a recording came from, typed: simulated, real or emulated, and where the
sensor was and how it moved.

The recording format (:mod:`processing.recording`) is the one place that turns a
recording's metadata into a :class:`Provenance` (``Recording.provenance``) and checks
it when a file is read; everything else reads the typed fields, not metadata keys.

In the metadata (and so in the file, ``docs/recording-format.md``)::

    provenance   "simulated" | "real" | "emulated"   (files before it: "simulated"
                 when ``simulated`` is true, else "real")
    simulated    bool, kept for readers of older versions (true only if simulated)
    scene        the scene's name (simulated and emulated recordings)
    pose         {position_m, yaw_deg, pitch_deg, roll_deg, time_s} at the emission
    pose_index   the pose's index in the scene's trajectory
    motion       {velocity_m_s, angular_velocity_deg_s, ...} during the measurement
    timestamp    Unix time of a recorded (real or emulated) measurement, seconds

An emulated recording is one taken through the USB driver from the emulated sensor
(``acousim record --emulate``): its samples are a simulation, decoded from PDM.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from .errors import InputError

__all__ = ["KINDS", "Kind", "Provenance", "SensorMotion", "SensorPose", "provenance_metadata"]

Kind = Literal["simulated", "real", "emulated"]
KINDS: tuple[str, ...] = get_args(Kind)


@dataclass(frozen=True)
class SensorPose:
    """The sensor's pose at the emission: position (3,) in metres, yaw/pitch/roll in
    radians, its time in the trajectory in seconds."""

    position_m: tuple[float, float, float]
    yaw_rad: float = 0.0
    pitch_rad: float = 0.0
    roll_rad: float = 0.0
    time_s: float = 0.0


@dataclass(frozen=True)
class SensorMotion:
    """The sensor's velocity (3,) in m/s and turn rate (3,) in rad/s (world frame)
    during the measurement."""

    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angular_velocity_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Provenance:
    """Where a recording came from (see the module docstring)."""

    kind: Kind
    scene: str | None = None
    pose: SensorPose | None = None
    pose_index: int | None = None
    motion: SensorMotion | None = None
    timestamp_s: float | None = None

    @property
    def simulated(self) -> bool:
        """True for a simulation (not for an emulated recording, nor a real one)."""
        return self.kind == "simulated"

    @classmethod
    def from_metadata(cls, meta: dict, *, file=None, key: str = "metadata") -> Provenance:
        """Read from a recording's metadata; an InputError names the key and value."""
        kind = meta.get("provenance")
        if kind is None:  # files written before the field: simulated or real
            kind = "simulated" if meta.get("simulated") else "real"
        if kind not in KINDS:
            raise InputError(
                f"must be one of {', '.join(KINDS)}",
                file=file,
                key=f"{key}: provenance",
                value=kind,
            )
        scene = meta.get("scene")
        index = meta.get("pose_index")
        stamp = meta.get("timestamp")
        return cls(
            kind,
            scene=str(scene) if scene is not None else None,
            pose=_pose(meta.get("pose")),
            pose_index=int(index) if isinstance(index, int | float) else None,
            motion=_motion(meta.get("motion"), file, key),
            timestamp_s=float(stamp) if _finite(stamp) else None,
        )


def provenance_metadata(kind: Kind) -> dict:
    """The metadata entries that say `kind` (``provenance`` and the older
    ``simulated``), for the code that makes recordings."""
    if kind not in KINDS:
        raise ValueError(f"provenance kind must be one of {KINDS}, got {kind!r}")
    return {"provenance": kind, "simulated": kind == "simulated"}


def _finite(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _pose(p) -> SensorPose | None:
    """A pose as the files store it (degrees; checked by the recording format)."""
    if not isinstance(p, dict) or "position_m" not in p:
        return None
    yaw, pitch, roll = np.deg2rad([p.get(k, 0.0) for k in ("yaw_deg", "pitch_deg", "roll_deg")])
    return SensorPose(
        tuple(float(v) for v in p["position_m"]),  # type: ignore[arg-type]
        float(yaw),
        float(pitch),
        float(roll),
        float(p.get("time_s", 0.0)),
    )


def _motion(m, file, key: str) -> SensorMotion | None:
    if m is None:
        return None
    try:
        v = np.asarray(m.get("velocity_m_s", (0.0, 0.0, 0.0)), float).reshape(3)
        w = np.deg2rad(np.asarray(m.get("angular_velocity_deg_s", (0.0, 0.0, 0.0)), float))
        w = w.reshape(3)
        if not (np.isfinite(v).all() and np.isfinite(w).all()):
            raise ValueError("not finite")
    except (TypeError, ValueError, AttributeError):
        raise InputError(
            "must be {velocity_m_s: [3 numbers], angular_velocity_deg_s: [3 numbers]}",
            file=file,
            key=f"{key}: motion",
            value=m,
        ) from None
    return SensorMotion(tuple(v.tolist()), tuple(w.tolist()))  # type: ignore[arg-type]
