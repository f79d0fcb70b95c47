"""A robot's rig: several sonars and LiDARs mounted on one body, firing on a schedule.

The body moves as a single sensor does today (a pose, a pose with a velocity and a
turn rate, or a trajectory: :class:`Rig` ``poses`` and ``motion``); each sonar
(:class:`RigSonar`) is a :class:`~acousim.scene.model.Sensor` (its own array,
emitter, call and sample rate) with a name, a :class:`Mount` (its extrinsic pose in
the body frame) and a :class:`Firing` schedule (a rate and an offset, or an explicit
list of times).  LiDARs are :class:`~acousim.scene.lidar.Lidar` whose own mounting
(``position_m``, ``rotation_deg``) places them in the body frame.

Frames: body and sensor frames are x forward, y left, z up; a mount's rotation is
``Rz(yaw) Ry(pitch) Rx(roll)`` (sensor -> body), as a pose's (sensor -> world).  A
sensor's pose in the world at time t is the body's pose then composed with its mount
(:meth:`Mount.place`); in motion its trajectory is the body's carrying the mount
(:class:`MountedTrajectory`).  The simulation is :mod:`acousim.rig`.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np
from scipy.spatial.transform import Rotation

from acousim.scene.lidar import Lidar
from acousim.scene.model import Sensor
from acousim.scene.pose import Pose, rotation
from acousim.scene.trajectory import Trajectory, placed
from processing.base.errors import InputError
from processing.base.settings import Setting, check, setting, validate

__all__ = [
    "Mount",
    "Firing",
    "FiringMode",
    "RigSonar",
    "Rig",
    "MountedTrajectory",
    "Measurement",
    "schedule",
    "sonar_scene",
]

#: how the sonars of a rig share their rate: one after another, evenly spaced over
#: the period ("round_robin"), or all at the same instants ("simultaneous")
FiringMode = Literal["round_robin", "simultaneous"]
#: a mount's rotation: roll, pitch, yaw (deg), the scene file's ``rotation_deg``
ROTATION_DEG = Setting("vector", (0.0, 0.0, 0.0), "deg", -360, 360, "roll, pitch, yaw", length=3)
#: a sonar's firing rate when neither it nor the rig gives one (Hz)
DEFAULT_RATE_HZ = 10.0


@dataclass(frozen=True, eq=False)
class Mount:
    """A sensor's extrinsic pose in the body frame: position (3,) m, and roll, pitch,
    yaw in radians (:meth:`degrees` takes degrees)."""

    position_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        p = np.asarray(self.position_m, float).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)) or np.any(np.abs(p) > 100):
            raise InputError(
                "must be 3 finite numbers within +-100 m", key="Mount.position_m", value=p
            )
        object.__setattr__(self, "position_m", p)
        for name in ("roll_rad", "pitch_rad", "yaw_rad"):
            v = getattr(self, name)
            if isinstance(v, bool) or not np.isfinite(v):
                raise InputError("must be a finite number", key=f"Mount.{name}", value=v)
            object.__setattr__(self, name, float(v))

    @classmethod
    def degrees(cls, position_m=(0.0, 0.0, 0.0), rotation_deg=(0.0, 0.0, 0.0)) -> Mount:
        """A mount at `position_m` turned by `rotation_deg` (roll, pitch, yaw; degrees,
        each within +-360, checked as the scene file's ``mount.rotation_deg``)."""
        angles = check(ROTATION_DEG, rotation_deg, "Mount.degrees.rotation_deg")
        roll, pitch, yaw = np.deg2rad(angles)
        return cls(position_m, float(roll), float(pitch), float(yaw))

    @property
    def rotation(self) -> np.ndarray:
        """Sensor -> body rotation (3, 3)."""
        return rotation(self.yaw_rad, self.pitch_rad, self.roll_rad)

    def place(self, body: Pose) -> Pose:
        """The sensor's pose in the world when the body is at `body` (same time)."""
        R = body.rotation @ self.rotation
        yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX")
        return Pose(body.to_world(self.position_m), yaw, pitch, roll, time_s=body.time_s)

    def to_body(self, points_sensor: np.ndarray) -> np.ndarray:
        """Sensor-frame points (..., 3) in the body frame."""
        return np.asarray(points_sensor) @ self.rotation.T + self.position_m

    def to_sensor(self, points_body: np.ndarray) -> np.ndarray:
        """Body-frame points (..., 3) in the sensor frame."""
        return (np.asarray(points_body) - self.position_m) @ self.rotation

    def to_dict(self) -> dict:
        """The mount as files write it (degrees)."""
        return {
            "position_m": self.position_m.tolist(),
            "rotation_deg": np.rad2deg([self.roll_rad, self.pitch_rad, self.yaw_rad]).tolist(),
        }


@dataclass(frozen=True, eq=False)
class MountedTrajectory(Trajectory):
    """A mounted sensor's motion: the body's `body` trajectory carrying `mount`
    (the same interface as :class:`Trajectory`; its own fields are the body's)."""

    body: Trajectory = None  # type: ignore[assignment]  # always given: see of()
    mount: Mount = None  # type: ignore[assignment]

    @classmethod
    def of(cls, body: Trajectory | None, mount: Mount) -> MountedTrajectory | None:
        """`mount` carried by `body` (None: a frozen body, None)."""
        if body is None:
            return None
        fields = {f.name: getattr(body, f.name) for f in dataclasses.fields(Trajectory)}
        return cls(**fields, body=body, mount=mount)

    def position(self, t_s) -> np.ndarray:
        """Sensor position (..., 3) at times `t_s` (...)."""
        R = self.body.rotation(t_s)
        return self.body.position(t_s) + R @ self.mount.position_m

    def rotation(self, t_s) -> np.ndarray:
        """Rotation sensor -> world (..., 3, 3) at times `t_s` (...)."""
        return self.body.rotation(t_s) @ self.mount.rotation

    def to_world(self, points_sensor: np.ndarray, t_s) -> np.ndarray:
        """Sensor-frame points (P, 3) at times (...): world positions (..., P, 3) (as
        :meth:`Trajectory.to_world`, the body's rotation evaluated once)."""
        body = self.body.rotation(t_s)
        R = body @ self.mount.rotation
        p = self.body.position(t_s) + body @ self.mount.position_m
        return placed(R, np.asarray(points_sensor, float), p)

    def velocity(self, t_s: float) -> np.ndarray:
        """Velocity (3,) m/s of the sensor's origin at `t_s` (world frame): the body's
        plus its turn carrying the lever arm."""
        arm = self.body.rotation(float(t_s)) @ self.mount.position_m
        return self.body.velocity(t_s) + np.cross(self.body.angular_velocity(t_s), arm)


@dataclass(frozen=True)
class Firing:
    """When a sonar fires: every ``1 / rate_hz`` s (unset: 10 Hz) from ``offset_s``
    after the body's first pose (`count` times; None: over the body's trajectory,
    once for a body with one pose), or at the explicit times `times_s` (s, the body's
    clock), not both: the scene file's ``firing`` table."""

    rate_hz: float | None = setting(
        None, "Hz", 1e-3, 1e4, "firing rate; unset: 10 Hz (none with times_s)", kind="float"
    )
    offset_s: float = setting(0.0, "s", 0.0, 1e7, "first firing after the body's first pose")
    count: int | None = setting(
        None, "", 1, 10**7, "number of firings; unset: over the body's trajectory", kind="int"
    )
    times_s: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        validate(self, prefix="Firing")
        if self.times_s is None:
            if self.rate_hz is None:
                object.__setattr__(self, "rate_hz", DEFAULT_RATE_HZ)
            return
        given = [k for k in ("rate_hz", "count") if getattr(self, k) is not None]
        given += ["offset_s"] if self.offset_s else []
        if given:
            raise InputError(
                f"times_s and {' and '.join(given)} both given: a sonar fires at explicit "
                "times or at a rate, not both",
                key="Firing.times_s",
                value=self.times_s,
            )
        t = np.asarray(self.times_s, float).reshape(-1)
        if not t.size or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise InputError(
                "must be a non-empty list of increasing times (s)",
                key="Firing.times_s",
                value=self.times_s,
            )
        object.__setattr__(self, "times_s", tuple(t.tolist()))

    def times(self, start_s: float, span_s: float) -> np.ndarray:
        """Firing times (F,) s for a body whose poses run from `start_s` over `span_s`."""
        if self.times_s is not None:
            return np.array(self.times_s)
        assert self.rate_hz is not None  # a rate, or explicit times (checked on construction)
        period = 1.0 / self.rate_hz
        if self.count is not None:
            n = int(self.count)
        elif span_s > 0:
            n = int(np.floor((span_s - self.offset_s) / period + 1e-9)) + 1
        else:
            n = 1
        return start_s + self.offset_s + period * np.arange(max(n, 0))


def schedule(
    n: int, rate_hz: float = DEFAULT_RATE_HZ, mode: FiringMode = "round_robin"
) -> list[Firing]:
    """The firings of `n` sonars each at `rate_hz`: round robin (sonar k offset by
    k / (n rate)) or simultaneous (all at the same instants)."""
    if mode not in ("round_robin", "simultaneous"):
        raise InputError("must be 'round_robin' or 'simultaneous'", key="firing", value=mode)
    step = 1.0 / (n * rate_hz) if mode == "round_robin" else 0.0
    return [Firing(rate_hz, k * step) for k in range(n)]


@dataclass(frozen=True, eq=False)
class RigSonar:
    """One sonar of a rig: its `sensor` (array, emitter, call, sample rate, directivity;
    its poses and motion are the rig's, not read), `name`, `mount` and `firing`
    (None, the default: the rig's schedule, :class:`Rig` ``firing`` and ``rate_hz``,
    round robin by default, as a scene file's sonar without ``firing``)."""

    name: str
    sensor: Sensor
    mount: Mount = field(default_factory=Mount)
    firing: Firing | None = None


@dataclass(frozen=True)
class Measurement:
    """One firing of a rig: sonar `sonar` (index) fires at `time_s`, from `pose`
    (the sonar's, world frame); `index`: its place among all the rig's
    measurements (time order)."""

    index: int
    sonar: int
    time_s: float
    pose: Pose


@dataclass(frozen=True, eq=False)
class Rig:
    """Sonars and LiDARs on one body.

    poses : the body's poses (one, or a trajectory sampled at its rate); motion: its
        :class:`Trajectory` (None: every measurement frozen, at the pose last
        reached).
    firing, rate_hz : the schedule of the sonars without their own ``firing``
        (:func:`schedule`): "round_robin" (the default) or "simultaneous", each sonar
        at `rate_hz` (None: the body's trajectory rate, 1 / the poses' spacing, or
        10 Hz for one pose), as the scene file's ``[rig]``.
    crosstalk : every call of every sonar in the recordings of all the others (and
        its own later ones) that it reaches; false: each recording hears its own call
        only.
    earlier_calls : with crosstalk, the calls emitted before a recording's own
        emission are heard too (the late paths of a call that reach its window); false
        leaves them out, and hears only the calls emitted during the window: an
        approximation, cheaper (on the corridor rig the earlier call is about half
        of the crosstalk's cost and lies 71 to 83 dB under the recording; in a small
        reverberant room its later echoes can be much stronger: BENCHMARKS.md "Rig").
    """

    sonars: tuple[RigSonar, ...]
    poses: tuple[Pose, ...] = field(default_factory=lambda: (Pose(np.zeros(3)),))
    motion: Trajectory | None = None
    lidars: tuple[Lidar, ...] = ()
    crosstalk: bool = setting(True, doc="every call heard by every sonar it reaches")
    earlier_calls: bool = setting(True, doc="with crosstalk, the calls emitted before a window")
    firing: FiringMode = setting(
        "round_robin", choices=get_args(FiringMode), doc="schedule of sonars without their own"
    )
    rate_hz: float | None = setting(
        None, "Hz", 1e-3, 1e4, "each sonar's rate; unset: the body's trajectory rate, or 10 Hz",
        kind="float",
    )  # fmt: skip

    def __post_init__(self) -> None:
        validate(self, prefix="Rig")
        sonars = tuple(self.sonars)
        if not sonars or not all(isinstance(s, RigSonar) for s in sonars):
            raise InputError("must hold at least one RigSonar", key="Rig.sonars")
        names = [s.name for s in sonars]
        for k, n in enumerate(names):  # names become ROS topics and TF frames
            if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", str(n)):
                raise InputError(
                    "a sonar's name must start with a letter and hold letters, digits and _",
                    key=f"Rig.sonars[{k}].name",
                    value=n,
                )
        if len(set(names)) != len(names):
            raise InputError("sonar names must be unique", key="Rig.sonars", value=names)
        poses = (self.poses,) if isinstance(self.poses, Pose) else tuple(self.poses)
        if not poses:
            raise InputError("must hold at least one Pose", key="Rig.poses")
        if self.motion is not None and not isinstance(self.motion, Trajectory):
            raise InputError("must be None or a Trajectory", key="Rig.motion", value=self.motion)
        if not all(isinstance(x, Lidar) for x in self.lidars):
            raise InputError("must hold Lidar objects", key="Rig.lidars")
        object.__setattr__(self, "poses", poses)
        object.__setattr__(self, "sonars", self._scheduled(sonars))
        object.__setattr__(self, "lidars", tuple(self.lidars))
        self._check_firings()
        if self.crosstalk:
            self._check_hearing()

    def _check_hearing(self) -> None:
        """With crosstalk every sonar records every other's call: its sample rate must
        be above twice the highest frequency of each (as of its own call)."""
        for k, hearing in enumerate(self.sonars):
            fs = hearing.sensor.sample_rate_hz
            for emitting in self.sonars:
                top = max(emitting.sensor.call.band_hz)
                if top >= fs / 2:
                    raise InputError(
                        f"is below twice the highest frequency of the call of sonar "
                        f"{emitting.name!r} ({top:g} Hz), which sonar {hearing.name!r} "
                        "hears (crosstalk): raise it, or turn crosstalk off",
                        key=f"Rig.sonars[{k}].sensor.sample_rate_hz",
                        value=fs,
                    )

    def _scheduled(self, sonars: tuple[RigSonar, ...]) -> tuple[RigSonar, ...]:
        """`sonars`, those without a firing given the rig's schedule (sonar k of N
        its k-th firing of :func:`schedule`)."""
        if all(s.firing is not None for s in sonars):
            return sonars
        rate = self.rate_hz
        if rate is None:
            span = self.poses[-1].time_s - self.poses[0].time_s
            # 12 digits: 3 poses over 0.3 s are 10 Hz, not 9.999999999999998
            rate = float(f"{(len(self.poses) - 1) / span:.12g}") if span > 0 else DEFAULT_RATE_HZ
        firings = schedule(len(sonars), rate, self.firing)
        return tuple(
            s if s.firing is not None else dataclasses.replace(s, firing=f)
            for s, f in zip(sonars, firings)
        )

    def _check_firings(self) -> None:
        """Every firing within the body's trajectory (its poses' times): beyond it
        the body would be extrapolated (through a wall); a body of one pose fires
        at any time (frozen, or moving at its velocity)."""
        start, end = self.poses[0].time_s, self.poses[-1].time_s
        if len(self.poses) < 2:
            return
        for k, f in enumerate(self._firings()):
            t = f.times(start, end - start)
            out = t[(t < start - 1e-9) | (t > end + 1e-9)]
            if t.size and not out.size:
                continue
            field_ = "times_s" if f.times_s is not None else "count" if f.count else "offset_s"
            value = getattr(f, field_)
            when = f"fires at {out[0]:g} s" if out.size else "never fires"
            raise InputError(
                f"{when}, outside the body's trajectory ({start:g} to {end:g} s): the body's "
                "pose there is unknown",
                key=f"Rig.sonars[{k}].firing.{field_}",
                value=value,
            )

    def _firings(self) -> list[Firing]:
        """Each sonar's firing (the rig's schedule filled in by ``__post_init__``)."""
        out = [s.firing for s in self.sonars]
        if any(f is None for f in out):
            raise ValueError("a sonar without its firing: Rig.__post_init__ fills them in")
        return [f for f in out if f is not None]

    def body_pose(self, t_s: float) -> Pose:
        """The body's pose at `t_s` (on its trajectory; frozen: the last pose reached)."""
        if self.motion is not None:
            return self.motion.pose(t_s)
        times = np.array([p.time_s for p in self.poses])
        i = int(np.clip(np.searchsorted(times, t_s + 1e-12, side="right") - 1, 0, len(times) - 1))
        p = self.poses[i]
        return Pose(p.position_m, p.yaw_rad, p.pitch_rad, p.roll_rad, time_s=float(t_s))

    def sonar_motion(self, k: int) -> MountedTrajectory | None:
        """Sonar k's trajectory (None: a frozen body)."""
        return MountedTrajectory.of(self.motion, self.sonars[k].mount)

    def measurements(self) -> list[Measurement]:
        """Every firing of every sonar, in time order (ties: in the sonars' order)."""
        start = self.poses[0].time_s
        span = self.poses[-1].time_s - start
        fired = [(float(t), k) for k, f in enumerate(self._firings()) for t in f.times(start, span)]
        fired.sort()
        return [
            Measurement(i, k, t, self.sonars[k].mount.place(self.body_pose(t)))
            for i, (t, k) in enumerate(fired)
        ]

    def pair_array(self, j: int, k: int):
        """The emitter of sonar j and the microphones of sonar k, both in sonar j's
        frame (a :class:`processing.Array` with k's layout); sonar k's own for j = k."""
        if j == k:
            return self.sonars[k].sensor.array
        a_k = self.sonars[k].sensor.array
        mj, mk = self.sonars[j].mount, self.sonars[k].mount
        mics = mj.to_sensor(mk.to_body(a_k.positions_m))
        emitter = self.sonars[j].sensor.array.emitter_m
        return dataclasses.replace(a_k, positions_m=mics, emitter_m=emitter)

    def lidar_on(self, k: int, n: int = 0) -> Lidar | None:
        """LiDAR `n` (None: the rig has none) mounted in sonar k's frame (its mounting,
        ``position_m`` and ``rotation_deg``, from the body's to k's): the scan
        recorded beside k's recordings."""
        if n >= len(self.lidars):
            return None
        lidar = self.lidars[n]
        mount = self.sonars[k].mount
        T = lidar.to_sensor()  # LiDAR -> body
        R = mount.rotation.T @ T[:3, :3]
        yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX")
        return dataclasses.replace(
            lidar,
            position_m=tuple(mount.to_sensor(T[:3, 3]).tolist()),
            rotation_deg=tuple(np.rad2deg([roll, pitch, yaw]).tolist()),
        )

    def pair_axis(self, j: int, k: int) -> np.ndarray:
        """Sonar k's axis (3,) in sonar j's frame (where k's microphones face)."""
        mj, mk = self.sonars[j].mount, self.sonars[k].mount
        return mj.rotation.T @ mk.rotation[:, 0]


def sonar_scene(scene, name: str | None, mount: Mount | None = None):
    """The scene of a rig's sonar `name` alone (:class:`~acousim.scene.model.Scene`,
    no rig, no crosstalk): its sensor at the poses of its firings (pose i: its i-th
    firing, in time order), carried by the body's motion, with the rig's first LiDAR
    on it; `mount` replaces its declared one.  A scene without a rig is returned as
    it is (`name` must then be None).  Raises InputError naming ``--sensor`` and the
    rig's sonars when `name` is None or not one of them (what ``compare``,
    ``calibrate`` and ``dataset`` take)."""
    rig = scene.rig
    if rig is None:
        if name is not None:
            raise InputError(
                f"scene {scene.name!r} has one sensor, not a rig", key="--sensor", value=name
            )
        return scene
    names = [s.name for s in rig.sonars]
    if name not in names:
        raise InputError(
            f"scene {scene.name!r} is a rig of {len(names)} sonar(s) ({', '.join(names)}): "
            "name the one to take",
            key="--sensor",
            value=name,
        )
    k = names.index(name)
    sonar = rig.sonars[k]
    if mount is not None:
        sonars = list(rig.sonars)
        sonars[k] = dataclasses.replace(sonar, mount=mount)
        rig = dataclasses.replace(rig, sonars=tuple(sonars))
    poses = tuple(m.pose for m in rig.measurements() if m.sonar == k)
    sensor = dataclasses.replace(
        sonar.sensor,
        poses=poses,
        rate_hz=None,
        motion=rig.sonar_motion(k),
        lidar=rig.lidar_on(k),
    )
    return dataclasses.replace(scene, sensor=sensor, rig=None)
