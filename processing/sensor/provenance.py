"""Where a recording came from, typed: simulated, real or emulated, and where the
sensor was and how it moved.

The recording format (:mod:`processing.formats.native`) is the one place that turns a
recording's metadata into a :class:`Provenance` (``Recording.provenance``) and checks
it when a file is read; everything else reads the typed fields, not metadata keys.

In the metadata (and so in the file, ``docs/recording-format.md``)::

    provenance   "simulated" | "real" | "emulated"   (files before it: "simulated"
                 when ``simulated`` is true, else "real")
    simulated    bool, kept for readers of older versions (true only if simulated)
    scene        the scene's name (simulated and emulated recordings)
    scene_file   the scene file simulated, or null
    max_range_m  the range the simulation traced, m
    n_paths      the paths the simulation rendered
    sample       a dataset sample's drawn parameters (acousim.dataset, CHIRP shards)
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
from typing import Any, Literal, get_args

import numpy as np

from processing.base.errors import InputError
from processing.base.frames import rotation

__all__ = [
    "KINDS",
    "Kind",
    "Provenance",
    "SensorMotion",
    "SensorPose",
    "kind_of",
    "provenance_metadata",
]

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

    def matrix(self) -> np.ndarray:
        """The 4x4 transform sensor -> world."""
        T = np.eye(4)
        T[:3, :3] = rotation(self.yaw_rad, self.pitch_rad, self.roll_rad)
        T[:3, 3] = self.position_m
        return T


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
    scene_file: str | None = None
    """The scene file a simulation ran (None: not known, or not simulated)."""
    max_range_m: float | None = None
    """The range a simulation traced, m (None: not simulated)."""
    n_paths: int | None = None
    """The paths a simulation rendered (None: not simulated)."""
    sample: dict[str, Any] | None = None
    """A dataset sample's drawn parameters (:mod:`acousim.dataset`), else None."""

    @property
    def simulated(self) -> bool:
        """True for a simulation (not for an emulated recording, nor a real one)."""
        return self.kind == "simulated"

    @classmethod
    def from_metadata(cls, meta: dict, *, file=None, key: str = "metadata") -> Provenance:
        """Read from a recording's metadata; an InputError names the key and value."""
        kind = kind_of(meta)
        if kind not in KINDS:
            raise InputError(
                f"must be one of {', '.join(KINDS)}",
                file=file,
                key=f"{key}: provenance",
                value=kind,
            )
        scene, scene_file = meta.get("scene"), meta.get("scene_file")
        index, paths = meta.get("pose_index"), meta.get("n_paths")
        stamp, reach = meta.get("timestamp"), meta.get("max_range_m")
        sample = meta.get("sample")
        return cls(
            kind,  # type: ignore[arg-type]
            scene=str(scene) if scene is not None else None,
            pose=_pose(meta.get("pose")),
            pose_index=int(index) if isinstance(index, int | float) else None,
            motion=_motion(meta.get("motion"), file, key),
            timestamp_s=float(stamp) if _finite(stamp) else None,
            scene_file=scene_file if isinstance(scene_file, str) else None,
            max_range_m=float(reach) if _finite(reach) and reach > 0 else None,
            n_paths=int(paths) if _finite(paths) else None,
            sample=dict(sample) if isinstance(sample, dict) else None,
        )


def kind_of(meta: dict) -> str:
    """The provenance kind a recording's metadata (or a message holding its keys) says:
    its ``provenance``, else, before the field, "simulated" when ``simulated`` is
    true and "real" otherwise (not checked: see :meth:`Provenance.from_metadata`)."""
    kind = meta.get("provenance")
    if kind is None:  # files written before the field: simulated or real
        kind = "simulated" if meta.get("simulated") else "real"
    return kind


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
