"""Continuous sensor motion: where the sensor is at any instant of a measurement.

A :class:`Trajectory` is a function of time (seconds, the trajectory's clock: pose i
of a file trajectory is at ``i / rate_hz``) giving the sensor's position (m, world
frame) and its rotation sensor -> world.  Two forms:

1. **Through poses** (:meth:`Trajectory.through`): positions by a cubic spline through
   the poses (natural ends; linear for two poses), orientations by spherical linear
   interpolation between consecutive poses (a constant angular velocity on each
   segment, ``R(t) = R_i exp(s log(R_i^T R_(i+1)))``, s the fraction of the segment:
   what :class:`scipy.spatial.transform.Slerp` computes, here also extrapolated past
   the last pose, so the last measurement window is covered).
2. **Constant rates** (:meth:`Trajectory.constant`): one pose with a velocity (m/s,
   world frame) and an angular velocity (rad/s, world frame: ``R(t) = exp(w t) R_0``;
   a positive z rate turns left).

Each pose is where the sensor is at the *start of the emission* of its measurement.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from acousim.scene.motion import MAX_SPEED_M_S, MAX_TURN_DEG_S
from acousim.scene.pose import Pose
from processing.base.errors import InputError
from processing.base.settings import Setting, check

__all__ = ["Trajectory", "RATES", "CONTINUOUS"]

#: the rates of a constant motion, declared once: the keys of ``[sensor.pose]`` and
#: the arguments of :meth:`Trajectory.constant` (there in rad/s)
RATES: dict[str, Setting] = {
    "velocity_m_s": Setting(
        "vector",
        (0.0, 0.0, 0.0),
        "m/s",
        -MAX_SPEED_M_S,
        MAX_SPEED_M_S,
        "velocity during measurements (world frame)",
        length=3,
    ),
    "angular_rate_deg_s": Setting(
        "vector",
        (0.0, 0.0, 0.0),
        "deg/s",
        -MAX_TURN_DEG_S,
        MAX_TURN_DEG_S,
        "turn rates about world x, y, z (+z turns left)",
        length=3,
    ),
}
#: ``[sensor.trajectory] continuous``: the sensor moves between its poses
CONTINUOUS = Setting("bool", True, doc="move between the poses; false: frozen poses")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Sensor motion; build it with :meth:`through` or :meth:`constant`.

    times_s (K,), positions_m (K, 3), rotations (K,) scipy Rotation; with K = 1 the
    motion is ``velocity_m_s`` and ``angular_velocity_rad_s`` (world frame) from
    ``times_s[0]``.
    """

    times_s: np.ndarray
    positions_m: np.ndarray
    rotations: Rotation
    velocity_m_s: np.ndarray
    angular_velocity_rad_s: np.ndarray

    @classmethod
    def constant(
        cls, pose: Pose, velocity_m_s=(0.0, 0.0, 0.0), angular_velocity_rad_s=(0.0, 0.0, 0.0)
    ) -> Trajectory:
        """A pose moving at a constant velocity (m/s) and turning at a constant rate
        (rad/s), both world frame and within :data:`RATES` (an InputError otherwise)."""
        v = np.array(check(RATES["velocity_m_s"], _listed(velocity_m_s), "velocity_m_s"))
        deg = RATES["angular_rate_deg_s"]
        rad = dataclasses.replace(deg, unit="rad/s", lo=np.deg2rad(deg.lo), hi=np.deg2rad(deg.hi))
        w = np.array(check(rad, _listed(angular_velocity_rad_s), "angular_velocity_rad_s"))
        return cls(
            np.array([pose.time_s], float),
            pose.position_m[None, :].copy(),
            Rotation.from_matrix(pose.rotation[None]),
            v,
            w,
        )

    @classmethod
    def through(cls, poses: tuple[Pose, ...] | list[Pose]) -> Trajectory:
        """The smooth motion through poses at increasing ``time_s``."""
        if len(poses) < 2:
            raise InputError("a trajectory through poses needs at least two poses", key="poses")
        t = np.array([p.time_s for p in poses], float)
        if not np.all(np.diff(t) > 0):
            raise InputError("pose times must increase", key="poses", value=t.tolist())
        pos = np.array([p.position_m for p in poses])
        rot = Rotation.from_matrix(np.array([p.rotation for p in poses]))
        return cls(t, pos, rot, np.zeros(3), np.zeros(3))

    @property
    def is_constant(self) -> bool:
        return self.times_s.size == 1

    def _spline(self) -> CubicSpline:
        """The position spline (only for a trajectory through poses: not constant)."""
        spline = self.__dict__.get("_spline_cache")
        if spline is None:
            # natural ends (zero acceleration): a straight line through two poses
            ends = ((2, np.zeros(3)), (2, np.zeros(3)))
            spline = CubicSpline(self.times_s, self.positions_m, bc_type=ends)
            self.__dict__["_spline_cache"] = spline
        return spline

    def position(self, t_s) -> np.ndarray:
        """Sensor position (..., 3) at times `t_s` (...)."""
        t = np.asarray(t_s, float)
        if self.is_constant:
            return self.positions_m[0] + (t - self.times_s[0])[..., None] * self.velocity_m_s
        return self._spline()(t)

    def rotation(self, t_s) -> np.ndarray:
        """Rotation sensor -> world (..., 3, 3) at times `t_s` (...).

        Rodrigues' formula on the segment's (or the constant motion's) rotation
        vector, the axis' cross-product matrices made once per trajectory: the same
        rotations as scipy's quaternions within rounding (1e-15), in a fifth of the
        time (:meth:`_turns`)."""
        t = np.asarray(t_s, float)
        flat = t.ravel()
        base, first, second, rate, start, _ = self._turns()
        k: int | np.ndarray = 0  # the segment (of each time)
        if not self.is_constant:
            k = np.searchsorted(self.times_s, flat, side="right") - 1
            k = np.clip(k, 0, self.times_s.size - 2)
            if k.size and k.min() == k.max():  # one segment (a measurement's): its matrices once
                k = int(k[0])
        angle = (flat - start[k]) * rate[k]
        s = np.sin(angle)[:, None, None]
        h = np.sin(0.5 * angle)
        v = (2 * h * h)[:, None, None]  # 1 - cos, without cancelling
        R = base[k] + s * first[k] + v * second[k]
        return R.reshape(*t.shape, 3, 3)

    def _turns(self):
        """Per segment j (one for a constant motion): ``R(t) = B_j + sin a F_j +
        (1 - cos a) S_j`` with ``a = (t - start_j) rate_j`` (rad): B_j the rotation
        at the segment's start, K_j the cross-product matrix of its rotation's unit
        axis, F_j and S_j ``B_j K_j`` and ``B_j K_j^2`` (body-frame axis: through
        poses) or ``K_j B_j`` and ``K_j^2 B_j`` (world frame: constant rates).
        Made once (B (J, 3, 3), F, S, rate (J,) rad/s, start (J,) s), with the
        angular velocities (J, 3) (rad/s, world frame)."""
        turns = self.__dict__.get("_turns_cache")
        if turns is not None:
            return turns
        mats = self.rotations.as_matrix()
        if self.is_constant:
            vec, span = self.angular_velocity_rad_s[None], np.ones(1)
        else:
            vec = (self.rotations[:-1].inv() * self.rotations[1:]).as_rotvec()
            span = np.diff(self.times_s)
            mats = mats[:-1]
        angle = np.linalg.norm(vec, axis=1)
        axis = vec / np.where(angle > 0, angle, 1.0)[:, None]
        K = np.zeros((len(vec), 3, 3))
        K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
        K = K - K.transpose(0, 2, 1)
        K2 = K @ K
        if self.is_constant:
            first, second = K @ mats, K2 @ mats
        else:
            first, second = mats @ K, mats @ K2
        rate = angle / span
        if self.is_constant:
            omega = self.angular_velocity_rad_s[None]
        else:  # the body frame's rotation vector turned into the world's
            omega = (mats @ vec[:, :, None])[:, :, 0] / span[:, None]
        turns = (mats, first, second, rate, self.times_s[: len(vec)], omega)
        self.__dict__["_turns_cache"] = turns
        return turns

    def to_world(self, points_sensor: np.ndarray, t_s) -> np.ndarray:
        """Sensor-frame points (P, 3) at times (...): world positions (..., P, 3)."""
        return placed(self.rotation(t_s), np.asarray(points_sensor, float), self.position(t_s))

    def velocity(self, t_s: float) -> np.ndarray:
        """Velocity (3,) m/s at time `t_s` (world frame)."""
        if self.is_constant:
            return self.velocity_m_s.copy()
        return self._spline()(float(t_s), 1)

    def angular_velocity(self, t_s: float) -> np.ndarray:
        """Angular velocity (3,) rad/s at time `t_s` (world frame)."""
        if self.is_constant:
            return self.angular_velocity_rad_s.copy()
        t = self.times_s
        i = int(np.clip(np.searchsorted(t, t_s, side="right") - 1, 0, t.size - 2))
        return self._turns()[5][i].copy()  # (R_(i+1) R_i^T as a rotation vector)

    def pose(self, t_s: float) -> Pose:
        """The pose at time `t_s`."""
        R = self.rotation(float(t_s))
        yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX")
        return Pose(self.position(float(t_s)), yaw, pitch, roll, time_s=float(t_s))


def placed(R: np.ndarray, points: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Points (P, 3) turned by the rotations `R` (..., 3, 3) and moved by `p` (..., 3):
    (..., P, 3), ``R x + p``; one matrix product (an einsum over the small axes
    costs five times more)."""
    lead = R.shape[:-2]
    turned = points @ R.reshape(-1, 3).T  # (P, G * 3): R_g x of every point and time
    out = turned.reshape(len(points), -1, 3).transpose(1, 0, 2).reshape(*lead, len(points), 3)
    return out + p[..., None, :]


def _listed(value):
    """A vector argument as a list (numpy arrays included) for :func:`check`."""
    return np.asarray(value).tolist() if isinstance(value, np.ndarray) else value
