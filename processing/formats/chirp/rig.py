"""A rig's recordings (several sonars on one body, ``metadata["sensor"]`` and
``metadata["mount"]``: :mod:`acousim.rig`) as one CHIRP file, one acoustic sensor
group per sonar (written by :func:`processing.formats.chirp.write.write_chirp`).

The layout (``docs/export.md``, "A rig in one CHIRP file")::

    /  attrs reference_sensor="acoustic_sensor_00" (the rig's first sonar),
             n_reference_captures = its firings
    /sensors/acoustic_sensor_NN        one per sonar, in the rig's order; name = the
                                       sonar's name; 00 "reference_capture", the
                                       others "full_capture" (their own firings)
        calibration/to_origin          (4, 4): the sonar in the origin frame (sonar
                                       00's array centre): inv(mount_00) @ mount_NN
        calibration/receiver_relative_translations  (M_NN, 3) m
        data/signals (N_NN, T_NN, M_NN) float32, data/timestamps (N_NN,) s
        data/sync_to_reference_index   (n_reference_captures,): its firing nearest
                                       each reference capture (not for 00)
    /sensors/acoustic_transmitter_NN   its emitter (to_origin), call, emission times
    /sensors/odometry_00               one row per firing of any sonar (time order):
                                       base_link = the body
    /sensors/lidar_NN                  one per LiDAR, one row per firing: the scan
                                       started at it
    /transforms  base_link_to_origin = inv(mount_00) (the body frame is base_link)
    /acousim     capture_sensor, capture_row: each firing's group and row

So ``inv(base_link_to_origin) @ to_origin`` of group NN is sonar NN's mount (sensor
-> body), as the rig declares it.
"""

from __future__ import annotations

import h5py
import numpy as np

from processing.base.frames import pose_matrix
from processing.formats.chirp.names import ChirpFileError, lidar_name

__all__ = ["acoustic_name", "transmitter_name", "mount_matrix", "sonars_of", "nearest"]


def acoustic_name(n: int) -> str:
    """The CHIRP group of the rig's sonar `n`: ``acoustic_sensor_NN``."""
    return f"acoustic_sensor_{n:02d}"


def transmitter_name(n: int) -> str:
    """The CHIRP group of sonar `n`'s emitter: ``acoustic_transmitter_NN``."""
    return f"acoustic_transmitter_{n:02d}"


def mount_matrix(mount: dict) -> np.ndarray:
    """A mount as our metadata holds it (``position_m``, ``rotation_deg`` = roll,
    pitch, yaw in degrees) as the 4x4 transform sensor -> body."""
    roll, pitch, yaw = (float(v) for v in mount.get("rotation_deg", (0.0, 0.0, 0.0)))
    pose = {"position_m": mount["position_m"], "yaw_deg": yaw, "pitch_deg": pitch}
    return pose_matrix({**pose, "roll_deg": roll})


def sonars_of(recs) -> list[str | None]:
    """The sonars of recordings (``metadata["sensor"]``): in the rig's order
    (``metadata["rig"]``) where it lists them all, else as they first appear."""
    names = list(dict.fromkeys(r.metadata.get("sensor") for r in recs))
    rig = recs[0].metadata.get("rig")
    if isinstance(rig, list) and set(names) <= set(rig):
        return [n for n in rig if n in names]
    return names


def nearest(times: np.ndarray, at: np.ndarray) -> np.ndarray:
    """For each time of `at` (R,), the index into sorted `times` (N,) of the nearest
    (ties: the earlier)."""
    if len(times) == 1:
        return np.zeros(len(at), np.int64)
    i = np.clip(np.searchsorted(times, at), 1, len(times) - 1)
    return np.where(at - times[i - 1] <= times[i] - at, i - 1, i).astype(np.int64)


def mounts(path, recs, sonar_of: np.ndarray) -> list[np.ndarray]:
    """Each sonar's mount (4x4, sensor -> body) from its recordings' metadata; every
    recording of a sonar must say the same."""
    out: dict[int, np.ndarray] = {}
    for i, (r, n) in enumerate(zip(recs, sonar_of)):
        m = r.metadata.get("mount")
        if not isinstance(m, dict) or "position_m" not in m:
            raise ChirpFileError(
                "a rig's recordings carry their sonar's mount (metadata 'mount'); "
                "this one has none",
                file=path,
                key=f"recordings[{i}].metadata.mount",
            )
        T = mount_matrix(m)
        if n in out and not np.allclose(out[n], T, atol=1e-12):
            raise ChirpFileError(
                f"sonar {r.metadata.get('sensor')!r} has two mounts",
                file=path,
                key=f"recordings[{i}].metadata.mount",
            )
        out.setdefault(int(n), T)
    return [out[n] for n in sorted(out)]


def body_pose(pose, mount: np.ndarray) -> np.ndarray:
    """The body's pose (4x4, body -> world) from a sonar's `pose`
    (:class:`~processing.sensor.provenance.SensorPose`) and its `mount` (4x4)."""
    return pose.matrix() @ np.linalg.inv(mount)


def write_transforms(f: h5py.File, bodies: list[np.ndarray], mount0: np.ndarray) -> None:
    """base_link (the body) in the origin frame (sonar 00's); the ground frame when
    the body's height above our world's z = 0 plane is the same at every firing and
    it stays level."""
    g = f.create_group("transforms")
    to_origin = np.linalg.inv(mount0)
    g.create_dataset("base_link_to_origin", data=to_origin)
    z = np.array([B[2, 3] for B in bodies])
    level = all(np.allclose(B[2, :3], [0, 0, 1], atol=1e-11) for B in bodies)
    if np.ptp(z) < 1e-9 and level:
        ground = np.eye(4)
        ground[2, 3] = -z[0]  # ground -> body
        g.create_dataset("ground_to_origin", data=to_origin @ ground)
        g.attrs["origin_height_above_ground_m"] = float(z[0] + mount0[2, 3])
        g.attrs["base_link_height_above_ground_m"] = float(z[0])


def lidar_to_origin(path, recs, owner, to_origin_of, n: int = 0) -> np.ndarray:
    """LiDAR `n`'s mounting in the origin frame: each recording's scan mounting
    (LiDAR -> its sonar) carried into sonar 00's frame; one LiDAR on one body, so
    every recording must agree."""
    out = None
    for k, i in enumerate(owner):
        T = to_origin_of[k] @ recs[i].lidars[n].to_sensor
        if out is None:
            out = T
        elif not np.allclose(out, T, atol=1e-9):
            raise ChirpFileError(
                "CHIRP holds one LiDAR mounting; the scans of the rig's sonars place it "
                "at different points of the body",
                file=path,
                key=lidar_name(n),
            )
    return out
