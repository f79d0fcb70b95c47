"""What a moving sensor sees of each path (:func:`seen_moving`): the reception time
of the call's first sample at the moving array centre and the arrival direction
then, in the sensor's frame then (the static case and the definitions:
:mod:`acousim.trace.seen`)."""

from __future__ import annotations

import numpy as np

from acousim.kinematics.retarded import _retarded
from acousim.trace.seen import Seen, apparent
from processing.base.kernels import optional_kernel

__all__ = ["seen_moving", "MOTION_TABLE_STEP_S"]


def seen_moving(
    moving, kin, trajectory, pose, centre_sensor_m: np.ndarray, c: float, guess=None, arr=None
) -> Seen:
    """What the sensor sees of paths in motion (:class:`~acousim.trace.motion.following.
    MovingPaths` `moving`, :class:`~acousim.kinematics.SensorKinematics` `kin`):
    the reception time of the call's first sample at the array centre
    (`centre_sensor_m` (3,)) moving with `trajectory` (None: still at `pose`), and
    the direction of the anchor then, in the sensor frame then (the module
    docstring); apparent positions in the sensor frame and, through `pose`, the
    world.  `guess` (N,): reception times to start from (the microphones' mean);
    `arr`: the paths' :class:`~acousim.kinematics.Arrivals` (their last legs'
    start, solved already; None: solved here)."""
    if arr is not None and arr.anchor_m is not None:
        t_r, anchor = arr.leave_s, arr.anchor_m
    else:
        t_r, anchor, _ = _retarded(moving, kin, np.asarray(0.0), c, None)
        t_r, anchor = np.asarray(t_r)[0], np.asarray(anchor)[0]
    local = np.asarray(centre_sensor_m, float)

    if guess is None:
        t = t_r + np.linalg.norm(pose.to_world(local[None]) - anchor, axis=1) / c
    else:
        t = np.array(guess, float).reshape(-1)
    table = None if trajectory is None or not t.size else _Table(trajectory, pose.time_s, t)
    compiled = optional_kernel("acousim.kinematics._seen_kernel", "centre_seen")
    if table is not None and compiled is not None:
        out = (np.empty((t.size, 3)), np.empty((t.size, 3)), np.empty((t.size, 3)))
        # (copies: the kernel takes writable arrays, one compiled version)
        args = (np.array(t_r, float), np.array(anchor, float), np.array(local, float))
        frame = (pose.rotation, np.array(pose.position_m, float))
        compiled(t, *args, (table.times, table.rows, *_CONVERGED), float(c), frame, out)
        return Seen(t, *out)

    def centre(t):  # (N, 3) world, and the rotations (N, 3, 3) (None: the pose's)
        if table is None:
            return pose.to_world(local[None]), None
        rot, where = table(t)
        return rot @ local + where, rot

    stop, iterations = _CONVERGED
    for _ in range(iterations):  # a contraction of ratio v / c: stops within 1e-13 s
        where, rot = centre(t)
        new = t_r + np.linalg.norm(where - anchor, axis=1) / c
        done = np.max(np.abs(new - t), initial=0.0) < stop
        t = new
        if done:  # the centre where it is at the last t but v / c of 0.1 ns: 1e-13 m
            break
    return _seen(t, anchor, where, rot, pose, local, c)


#: the fixed point at the moving centre stops once no time changes by this (s), or
#: after this many iterations (compiled and numpy alike)
_CONVERGED = (1e-10, 20)


def _seen(t, anchor, where, rot, pose, local, c: float) -> Seen:
    """What the sensor sees of paths received at times `t` (N,) (s) from `anchor`
    (N, 3) at the centre `where` (N, 3) (world, m) turned by `rot` (N, 3, 3) (None:
    the pose's)."""
    u = anchor - where
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    u = u @ pose.rotation if rot is None else np.einsum("nji,nj->ni", rot, u)
    app = apparent(t, u, local, c)
    return Seen(t, u, app, pose.to_world(app))


#: the sensor's motion is tabulated at this step over the echoes' reception times and
#: interpolated linearly (error a h^2 / 8: below 1 um for a robot's accelerations)
MOTION_TABLE_STEP_S = 5e-4


class _Table:
    """The trajectory's rotation and position at times ``t0 + t`` for t spanning the
    reception times `t` (N,) (and 10 ms either side): tabulated once, interpolated."""

    def __init__(self, trajectory, t0: float, t: np.ndarray) -> None:
        lo, hi = float(t.min()) - 1e-2, float(t.max()) + 1e-2
        self.times = np.linspace(lo, hi, int(np.ceil((hi - lo) / MOTION_TABLE_STEP_S)) + 2)
        rot = trajectory.rotation(t0 + self.times).reshape(-1, 9)
        pos = np.asarray(trajectory.position(t0 + self.times), float).reshape(-1, 3)
        self.rows = np.hstack([rot, pos])  # (K, 12)

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (N, 3, 3) and positions (N, 3) at times `t` (N,)."""
        x = (t - self.times[0]) / (self.times[1] - self.times[0])
        i = np.clip(np.floor(x).astype(np.intp), 0, self.times.size - 2)
        w = (x - i)[:, None]
        rows = self.rows[i] * (1 - w) + self.rows[i + 1] * w
        return rows[:, :9].reshape(-1, 3, 3), rows[:, 9:]
