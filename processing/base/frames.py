"""Frames for CHIRP files: our poses (position, yaw/pitch/roll) as 4x4 transforms and
quaternions, and back.

Our convention (``acousim.scene.pose``): ``R = Rz(yaw) Ry(pitch) Rx(roll)`` maps
sensor coordinates to world, x forward, y left, z up, a positive pitch points the
sensor down. Quaternions are ``[x, y, z, w]`` (ROS order, CHIRP's odometry).
"""

from __future__ import annotations

import numpy as np

__all__ = ["rotation", "pose_matrix", "quaternion_of", "matrix_of_quaternion", "euler_of"]


def rotation(yaw_rad: float, pitch_rad: float = 0.0, roll_rad: float = 0.0) -> np.ndarray:
    """Sensor -> world rotation (3, 3), ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``.

    With y to the left, a positive rotation about y turns +x towards -z: a positive
    pitch points the sensor down.
    """
    cy, sy = np.cos(yaw_rad), np.sin(yaw_rad)
    cp, sp = np.cos(pitch_rad), np.sin(pitch_rad)
    cr, sr = np.cos(roll_rad), np.sin(roll_rad)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def pose_matrix(pose: dict) -> np.ndarray:
    """A pose as files hold it (``position_m``, ``yaw_deg``, ``pitch_deg``,
    ``roll_deg``) as the 4x4 transform sensor -> world."""
    T = np.eye(4)
    T[:3, :3] = rotation(
        *(np.deg2rad(float(pose.get(k, 0.0))) for k in ("yaw_deg", "pitch_deg", "roll_deg"))
    )
    T[:3, 3] = np.asarray(pose["position_m"], float)
    return T


def quaternion_of(R: np.ndarray) -> np.ndarray:
    """Unit quaternion [x, y, z, w] (w >= 0) of a rotation matrix (3, 3)."""
    R = np.asarray(R, float)
    tr = np.trace(R)
    # the largest of 4 w^2, 4 x^2, 4 y^2, 4 z^2 sets the numerically safe branch
    cand = np.array([1 + tr, 1 + 2 * R[0, 0] - tr, 1 + 2 * R[1, 1] - tr, 1 + 2 * R[2, 2] - tr])
    k = int(np.argmax(cand))
    s = 2 * np.sqrt(cand[k])  # 4 times the chosen component
    if k == 0:
        q = [R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1], s * s / 4]
    elif k == 1:
        q = [s * s / 4, R[0, 1] + R[1, 0], R[0, 2] + R[2, 0], R[2, 1] - R[1, 2]]
    elif k == 2:
        q = [R[0, 1] + R[1, 0], s * s / 4, R[1, 2] + R[2, 1], R[0, 2] - R[2, 0]]
    else:
        q = [R[0, 2] + R[2, 0], R[1, 2] + R[2, 1], s * s / 4, R[1, 0] - R[0, 1]]
    q = np.array(q) / s
    return q if q[3] >= 0 else -q


def matrix_of_quaternion(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion [x, y, z, w] (normalised here)."""
    x, y, z, w = np.asarray(q, float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def euler_of(R: np.ndarray) -> tuple[float, float, float]:
    """(yaw, pitch, roll) in radians with ``R = Rz(yaw) Ry(pitch) Rx(roll)``."""
    R = np.asarray(R, float)
    pitch = float(np.arcsin(np.clip(-R[2, 0], -1, 1)))
    if abs(R[2, 0]) < 1 - 1e-12:
        return float(np.arctan2(R[1, 0], R[0, 0])), pitch, float(np.arctan2(R[2, 1], R[2, 2]))
    return float(np.arctan2(-R[0, 1], R[1, 1])), pitch, 0.0  # gimbal lock: roll folded in yaw
