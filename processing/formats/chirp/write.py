"""CHIRP files: Cosys-Lab's HDF5 format for in-air sonar datasets, written and read.

CHIRP (Cosys-Lab Hybrid In-air sonar Recording Package, read by their ``chirppy``)
makes the acoustic array the reference sensor: its captures define the time grid,
every other sensor sits beside it with a 4x4 transform ``to_origin`` into the
*origin* frame (the array's centre; x forward, y left, z up: our sensor frame).
What we write (format version 2.1; ``docs/export.md`` maps every field to its
source)::

    /  attrs format="chirp", format_version="2.1", n_reference_captures=N,
             reference_sensor="acoustic_sensor_00"
    /sensors/acoustic_sensor_00        sensor_type "acoustic_sensor"
        calibration/to_origin          (4, 4) identity
        calibration/receiver_relative_translations  (M, 3) m
        data/signals                   (N, T, M) float32
        data/timestamps                (N,) s: time of each capture's first sample
    /sensors/acoustic_transmitter_00   sensor_type "acoustic_transmitter"
        calibration/to_origin          (4, 4): the emitter's position
        data/signals                   (L,) float32: the call sampled at the rate
        data/timestamps                (N,) s: start of each emission
    /sensors/odometry_00               (every recording posed) base_link = origin
        data/position, orientation (x, y, z, w), yaw, linear_velocity,
        angular_velocity, pose_covariance, twist_covariance, timestamps, ros_timestamps
    /sensors/lidar_00                  (every recording with a LiDAR scan; a rig's
                                       other LiDARs: lidar_01, ...)
        calibration/to_origin          (4, 4): the LiDAR's mounting
        data/points (N, P, 4) float32 [x, y, z, intensity], NaN-padded;
        data/point_counts, data/timestamps
    /transforms  base_link_to_origin (identity), ground_to_origin (constant height)
    /acousim     ours: what CHIRP has no place for (ground truth, metadata, the
                 call's parameters, emission index, speed of sound, array extras)

Every sensor we write is ``sync_mode = "reference_capture"``: one row per capture.
A rig's recordings (several sonars) have one acoustic sensor and transmitter per
sonar, the body as base_link (layout: :mod:`processing.formats.chirp.rig`).
A recording of K measurements becomes K captures. Reading (:mod:`processing.formats.chirp.read`)
takes the array, the rate, the call (ours; else fitted to the transmitter's samples,
:func:`processing.sensor.calls.fit_sweep`; else the `call` given), poses (odometry) and
scans (LiDAR) of any CHIRP file; what it lacks is a :class:`ChirpFileError` naming
the file and the field.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from numpy.typing import NDArray

from processing.base.atomic import atomic_path
from processing.base.errors import InputError
from processing.base.frames import quaternion_of
from processing.formats.chirp import rig
from processing.formats.chirp.names import (
    ACOUSTIC,
    ODOMETRY,
    OUR_SCHEMA,
    OUR_VERSION,
    OURS,
    TRANSMITTER,
    ChirpFileError,
    lidar_name,
    our_lidar,
)
from processing.sensor.arrays import Array
from processing.sensor.provenance import SensorMotion, SensorPose
from processing.sensor.recording import STORED_SEEN, Recording

__all__ = [
    "write_chirp",
    "ChirpFileError",
    "FORMAT_VERSION",
    "DEFAULT_PERIOD_S",
]

FORMAT_VERSION = "2.1"
DEFAULT_PERIOD_S = 0.1
"""Capture spacing (s) when the recordings' own times do not increase."""
_TRUTH = (
    ("position_world_m", "m"),
    ("position_sensor_m", "m"),
    ("amplitude", "1"),
    ("order", "1"),
    ("kind", None),
    ("velocity_world_m_s", "m/s"),
    ("emitter", None),
    *STORED_SEEN.items(),
)


# ---------------------------------------------------------------- writing


def write_chirp(
    path: str | Path,
    recordings: Sequence[Recording],
    *,
    start_time_s: float = 0.0,
    period_s: float = DEFAULT_PERIOD_S,
    checksum: bool = True,
    compression: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write recordings as one CHIRP file, atomically (:mod:`processing.base.atomic`).

    All must share the array, sample rate, call and length (CHIRP has one receiver
    array and one signals array per acoustic sensor); a rig's recordings (several
    ``metadata["sensor"]``, each with its ``metadata["mount"]``) per sonar, each
    sonar its own acoustic sensor (:mod:`processing.formats.chirp.rig`). Times: each
    capture's emission is at its recording's provenance ``timestamp_s`` (a real
    recording, Unix s) or its pose's ``time_s`` (a trajectory), plus `start_time_s`;
    measurement k of a recording k x `period_s` later; when those do not increase
    strictly (a rig: per sonar, never falling over the file), capture i is at
    `start_time_s` + i x `period_s`. Samples: float32 (float64 rounded: 2**-24 at
    most), a chunk per capture, HDF5's fletcher32 `checksum`, a sha256 per capture,
    `compression` "gzip", "lzf" or None. The same recordings give the same bytes.
    `progress(done, total)`: after each capture's samples and each recording's own
    data (ground truth, metadata) are written.
    """
    path = Path(path)
    recs = list(recordings)
    if not recs:
        raise ChirpFileError("no recordings to write", file=path)
    sonar_of = _check_sonars(path, recs)
    if not (np.isfinite(period_s) and period_s > 0):
        raise InputError("must be a positive number of seconds", key="period_s", value=period_s)
    caps, synthetic = _captures(recs, sonar_of, period_s, start_time_s)
    mounts = None if sonar_of is None else rig.mounts(path, recs, sonar_of)
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = "chirp"
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["n_reference_captures"] = caps.n_reference
        f.attrs["reference_sensor"] = ACOUSTIC
        f.create_group("sensors")
        step = _Steps(progress, len(caps.owner) + len(recs))
        opts = {"fletcher32": checksum, "compression": compression, "step": step}
        if mounts is not None:  # a rig: one acoustic group per sonar (chirp.rig)
            sums = _write_rig(f, path, recs, caps, mounts, opts)
        else:
            sums = _write_one(f, recs, caps, opts)
        ours = f.require_group(OURS)
        ours.attrs.update(schema=OUR_SCHEMA, schema_version=OUR_VERSION)
        ours.attrs.update(timestamps_synthetic=synthetic, period_s=float(period_s))
        for name, data in (("recording", caps.owner), ("measurement", caps.measure)):
            ours.create_dataset(f"capture_{name}", data=data.astype(np.int64))
        ours.create_dataset("capture_sha256", data=np.array(sums, dtype="S64"))
        _write_array_extras(ours, recs[0].array)
        if caps.sonar is not None:
            _write_rig_extras(ours, recs, caps)
        for i, rec in enumerate(recs):
            _write_recording_extras(ours.create_group(f"recordings/{i:06d}"), rec, checksum)
            step()
    return path


class _Steps:
    """Counts the writer's steps for a `progress(done, total)` callback (None: none)."""

    def __init__(self, progress: Callable[[int, int], None] | None, total: int) -> None:
        self.progress, self.total, self.done = progress, total, 0

    def __call__(self) -> None:
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total)


@dataclass(frozen=True)
class _Captures:
    """The file's captures (C,): capture k is measurement ``measure[k]`` of recording
    ``owner[k]``, emitted at ``emission[k]`` (s), its first sample at ``sample0[k]``
    (s); a rig's: ``sonar[k]``, its sonar (None: one sensor)."""

    owner: NDArray[np.int_]
    measure: NDArray[np.int_]
    emission: NDArray[np.float64]
    sample0: NDArray[np.float64]
    sonar: NDArray[np.int_] | None = None

    @property
    def n_reference(self) -> int:
        """The reference sensor's captures (all, or a rig's sonar 0's)."""
        return len(self.owner) if self.sonar is None else int(np.sum(self.sonar == 0))

    def of(self, n: int) -> _Captures:
        """Sonar `n`'s captures."""
        k = np.flatnonzero(self.sonar == n)
        return _Captures(self.owner[k], self.measure[k], self.emission[k], self.sample0[k])


def _captures(recs, sonar_of, period_s, start_time_s) -> tuple[_Captures, bool]:
    """The captures of `recs` (`sonar_of`: a rig's recordings' sonars) and whether
    their times are synthetic (see :func:`write_chirp`)."""
    owner = np.concatenate([np.full(r.n_measurements, i) for i, r in enumerate(recs)])
    measure = np.concatenate([np.arange(r.n_measurements) for r in recs])
    sonar = None if sonar_of is None else sonar_of[owner]
    provenance = [r.provenance for r in recs]
    emission, synthetic = _emission_times(provenance, owner, measure, period_s, sonar)
    emission = emission + float(start_time_s)
    sample0 = emission - np.array([recs[i].emission_index / recs[i].sample_rate_hz for i in owner])
    return _Captures(owner, measure, emission, sample0, sonar), synthetic


def _write_one(f: h5py.File, recs: list[Recording], caps: _Captures, opts: dict) -> list[bytes]:
    """One sensor's captures: acoustic sensor, transmitter, odometry, LiDAR."""
    sensors = f["sensors"]
    owner, emission = caps.owner, caps.emission
    sums = _write_acoustic(sensors, recs, caps, opts)
    _write_transmitter(sensors, recs[0], emission)
    provenance = [r.provenance for r in recs]
    if all(p.pose is not None for p in provenance):
        _write_odometry(sensors, provenance, owner, emission)
        _write_transforms(f, [provenance[i].pose for i in owner])
    for n in range(_n_lidars(recs)):
        _write_lidar(sensors, f, recs, owner, emission, n=n)
    return sums


def _check_sonars(path: Path, recs: list[Recording]) -> np.ndarray | None:
    """Each recording's sonar (index into :func:`.rig.sonars_of`) for a rig's
    recordings, of several sonars or of one named sonar with its mount (one rig's
    sonar alone: its body stays base_link), else None (one sensor); each sonar's
    recordings share array, rate, call and length (:func:`_check_one_sensor`)."""
    sonars = rig.sonars_of(recs)
    if len(sonars) == 1 and (sonars[0] is None or not all("mount" in r.metadata for r in recs)):
        _check_one_sensor(path, recs)
        return None
    if None in sonars:
        i = next(i for i, r in enumerate(recs) if r.metadata.get("sensor") is None)
        raise ChirpFileError(
            f"recordings of a rig's sonars ({', '.join(str(n) for n in sonars if n)}) and "
            "of a sensor without a name (metadata 'sensor') cannot share a file",
            file=path,
            key=f"recordings[{i}].metadata.sensor",
        )
    sonar_of = np.array([sonars.index(r.metadata.get("sensor")) for r in recs])
    for n in range(len(sonars)):
        _check_one_sensor(path, recs, np.flatnonzero(sonar_of == n).tolist())
    return sonar_of


def _check_one_sensor(path: Path, recs: list[Recording], which: list[int] | None = None) -> None:
    """Recordings `which` (all) share array, sample rate, call and length; their
    LiDAR scans one mounting."""
    which = list(range(len(recs))) if which is None else which
    a = recs[which[0]]
    for i in which[1:]:
        r = recs[i]
        for what, same in (
            ("array", np.array_equal(r.array.positions_m, a.array.positions_m)
             and np.array_equal(r.array.emitter_m, a.array.emitter_m)),
            ("sample rate", r.sample_rate_hz == a.sample_rate_hz),
            ("call", r.waveform == a.waveform),
            ("length (samples)", r.n_samples == a.n_samples),
        ):  # fmt: skip
            if not same:
                raise ChirpFileError(
                    f"CHIRP holds one array, sample rate, call and capture length per "
                    f"sensor; recording {i} has another {what} than recording {which[0]}"
                    + (f" (sonar {a.metadata['sensor']!r})" if len(which) < len(recs) else ""),
                    file=path,
                    key="recordings",
                    value=i,
                )
    for n in range(max(len(recs[i].lidars) for i in which)):
        lidars = [recs[i].lidars[n] for i in which if len(recs[i].lidars) > n]
        if any(not np.allclose(pc.to_sensor, lidars[0].to_sensor) for pc in lidars):
            raise ChirpFileError(
                f"CHIRP holds one mounting per LiDAR; the recordings' scans of LiDAR {n} differ",
                file=path,
                key=lidar_name(n),
            )


def _n_lidars(recs: list[Recording]) -> int:
    """The LiDARs every recording has a scan of (a LiDAR group has a row per capture)."""
    return min(len(r.lidars) for r in recs)


def _emission_times(provenance, owner, measure, period_s, sonar=None) -> tuple[np.ndarray, bool]:
    """Each capture's emission time (s) and whether they are synthetic (see write_chirp);
    `provenance` the recordings' :class:`~processing.sensor.provenance.Provenance`;
    `sonar` (a rig's, each capture's): the times increase per sonar and never
    decrease over the file (sonars firing together)."""
    base = []
    for p in provenance:
        t = p.timestamp_s
        if t is None and p.pose is not None:
            t = p.pose.time_s
        base.append(float(t) if t is not None and np.isfinite(t) else np.nan)
    t = np.array(base)[owner] + measure * period_s
    if sonar is not None:
        rising = all(np.all(np.diff(t[sonar == n]) > 0) for n in np.unique(sonar))
        if np.all(np.isfinite(t)) and np.all(np.diff(t) >= 0) and rising:
            return t, False
    elif np.all(np.isfinite(t)) and np.all(np.diff(t) > 0):
        return t, False
    return np.arange(len(owner)) * period_s, True


def _sensor(parent: h5py.Group, name: str, kind: str, to_origin=None) -> h5py.Group:
    g = parent.create_group(name)
    g.attrs.update(sensor_type=kind, reference_frame="origin", sync_mode="reference_capture")
    if to_origin is not None:
        g.create_dataset("calibration/to_origin", data=np.asarray(to_origin, np.float64))
    return g


def _write_acoustic(sensors, recs, caps: _Captures, opts, *, name=ACOUSTIC, to_origin=None):
    """The captures `caps` as acoustic sensor `name` (placed by `to_origin`, 4x4;
    identity): their sha256s."""
    first = recs[int(caps.owner[0])]
    M, T = first.array.n_mics, first.n_samples
    g = _sensor(sensors, name, "acoustic_sensor", np.eye(4) if to_origin is None else to_origin)
    g.attrs.update(sample_rate_hz=first.sample_rate_hz, num_channels=M, name=first.array.name)
    g.create_dataset(
        "calibration/receiver_relative_translations", data=first.array.positions_m
    ).attrs["units"] = "m"
    h5 = {k: opts[k] for k in ("fletcher32", "compression")}
    d = g.create_dataset(
        "data/signals", (len(caps.owner), T, M), np.float32, chunks=(1, T, M), **h5
    )
    sums = []
    for k, (i, j) in enumerate(zip(caps.owner, caps.measure)):
        x = recs[i].samples if recs[i].samples.ndim == 2 else recs[i].samples[j]
        block = np.ascontiguousarray(x.T, "<f4")
        d[k] = block
        sums.append(hashlib.sha256(block.data).hexdigest().encode())
        opts["step"]()
    g.create_dataset("data/timestamps", data=caps.sample0).attrs["units"] = "s"
    return sums


def _write_transmitter(
    sensors, rec: Recording, emission: np.ndarray, *, name=TRANSMITTER, to_origin=None
) -> h5py.Group:
    """`rec`'s emitter as transmitter `name`: its call, emitted at `emission` (s), its
    position in its sensor's frame, placed by the sensor's `to_origin` (4x4)."""
    at = np.eye(4)
    at[:3, 3] = rec.array.emitter_m
    g = _sensor(sensors, name, "acoustic_transmitter", at if to_origin is None else to_origin @ at)
    g.attrs["sample_rate_hz"] = rec.sample_rate_hz
    g.create_dataset("data/signals", data=rec.waveform.sampled(rec.sample_rate_hz).astype("f4"))
    g.create_dataset("data/timestamps", data=emission).attrs["units"] = "s"
    return g


def _write_rig(f, path, recs, caps: _Captures, mounts, opts) -> list[bytes]:
    """A rig's captures (``caps.sonar``) as one acoustic sensor and transmitter per
    sonar, placed by their `mounts` (4x4, sensor -> body) in sonar 0's frame; the
    body's odometry and the LiDAR one row per capture (layout: :mod:`.rig`)."""
    sensors, sonar, emission = f["sensors"], caps.sonar, caps.emission
    to_origin = [np.linalg.inv(mounts[0]) @ m for m in mounts]
    ref = np.flatnonzero(sonar == 0)
    sums: list[bytes] = [b""] * len(caps.owner)
    for n, label in enumerate(rig.sonars_of(recs)):
        mine = caps.of(n)
        got = _write_acoustic(
            sensors, recs, mine, opts, name=rig.acoustic_name(n), to_origin=to_origin[n]
        )
        sensors[rig.acoustic_name(n)].attrs["name"] = label  # the sonar's name
        for k, h in zip(np.flatnonzero(sonar == n), got):
            sums[k] = h
        tx = _write_transmitter(
            sensors, recs[int(mine.owner[0])], mine.emission,
            name=rig.transmitter_name(n), to_origin=to_origin[n],
        )  # fmt: skip
        if n:  # its own firings; the one nearest each reference capture
            sync = rig.nearest(mine.emission, emission[ref])
            for g in (sensors[rig.acoustic_name(n)], tx):
                g.attrs["sync_mode"] = "full_capture"
                g.create_dataset("data/sync_to_reference_index", data=sync)
    every = ref.astype(np.int64)  # odometry and LiDAR: one row per capture
    provenance = [r.provenance for r in recs]
    if all(p.pose is not None for p in provenance):
        mount_of = [mounts[n] for n in sonar]
        _write_odometry(sensors, provenance, caps.owner, emission, mount_of, every)
        bodies = [rig.body_pose(provenance[i].pose, m) for i, m in zip(caps.owner, mount_of)]
        rig.write_transforms(f, bodies, mounts[0])
    for n in range(_n_lidars(recs)):
        at = rig.lidar_to_origin(path, recs, caps.owner, [to_origin[s] for s in sonar], n)
        g = _write_lidar(sensors, f, recs, caps.owner, emission, at, n=n)
        g.attrs["sync_mode"] = "full_capture"
        g.create_dataset("data/sync_to_reference_index", data=every)
    return sums


def _write_rig_extras(ours: h5py.Group, recs, caps: _Captures) -> None:
    """Each capture's acoustic sensor (index NN) and row in it; the sonars' names;
    the arrays' extras of sonars 1.. (``array_NN``)."""
    sonar = caps.sonar
    rows = np.zeros(len(sonar), np.int64)
    for n in np.unique(sonar):
        rows[sonar == n] = np.arange(np.sum(sonar == n))
    ours.create_dataset("capture_sensor", data=sonar.astype(np.int64))
    ours.create_dataset("capture_row", data=rows)
    names = rig.sonars_of(recs)
    ours.attrs["sensors"] = json.dumps(names)
    for n in range(1, len(names)):
        _write_array_extras(ours, recs[int(caps.of(n).owner[0])].array, f"array_{n:02d}")


def _write_odometry(sensors, provenance, owner, emission, mounts_of=None, sync=None) -> None:
    """The pose per capture of base_link in odom (= our world), velocities in
    base_link; exact, so the covariances are zero.  base_link is the array (one
    sensor), or a rig's body: `mounts_of` (C, 4, 4) each capture's sonar mount, the
    body's velocity the sonar's less its lever arm's turn, `sync` (C,) each row's
    reference capture."""
    n = len(owner)
    g = _sensor(sensors, ODOMETRY, "odometry")
    if mounts_of is not None:
        g.attrs["sync_mode"] = "full_capture"
    spread = n > 1 and (mounts_of is None or np.ptp(emission) > 0)
    rate = 1 / np.median(np.diff(emission)) if spread else 0.0
    g.attrs.update(source="acousim", rate_hz=float(rate))
    pos, quat, yaw = np.zeros((n, 3)), np.zeros((n, 4)), np.zeros(n)
    lin, ang = np.zeros((n, 3)), np.zeros((n, 3))
    for k, i in enumerate(owner):
        p, motion = provenance[i].pose, provenance[i].motion or SensorMotion()
        v = np.asarray(motion.velocity_m_s, float)
        w = np.asarray(motion.angular_velocity_rad_s, float)
        if mounts_of is None:
            T, yaw[k] = p.matrix(), p.yaw_rad
        else:
            T = rig.body_pose(p, mounts_of[k])
            v = v - np.cross(w, p.matrix()[:3, 3] - T[:3, 3])  # the mount's lever arm
            yaw[k] = np.arctan2(T[1, 0], T[0, 0])
        pos[k], quat[k] = T[:3, 3], quaternion_of(T[:3, :3])
        lin[k], ang[k] = T[:3, :3].T @ v, T[:3, :3].T @ w
    columns = [
        ("position", pos, "m"),
        ("orientation", quat, None),
        ("yaw", yaw, "rad"),
        ("linear_velocity", lin, "m/s"),
        ("angular_velocity", ang, "rad/s"),
        ("pose_covariance", np.zeros((n, 6, 6)), None),
        ("twist_covariance", np.zeros((n, 6, 6)), None),
        ("timestamps", emission, "s"),
        ("ros_timestamps", emission, "s"),
    ]
    if sync is not None:
        columns.append(("sync_to_reference_index", sync, None))
    for name, data, units in columns:
        d = g.create_dataset(f"data/{name}", data=data)
        if units:
            d.attrs["units"] = units


def _write_transforms(f: h5py.File, poses: list[SensorPose]) -> None:
    """base_link is the origin (the array); the ground frame only when the sensor's
    height above our world's z = 0 plane is the same at every capture."""
    g = f.create_group("transforms")
    g.create_dataset("base_link_to_origin", data=np.eye(4))
    z = np.array([p.position_m[2] for p in poses])
    level = np.deg2rad(1e-9)  # pitch and roll under 1e-9 degrees
    flat = all(abs(a) < level for p in poses for a in (p.pitch_rad, p.roll_rad))
    if np.ptp(z) < 1e-9 and flat:
        ground = np.eye(4)
        ground[2, 3] = -z[0]
        g.create_dataset("ground_to_origin", data=ground)
        g.attrs["origin_height_above_ground_m"] = float(z[0])
        g.attrs["base_link_height_above_ground_m"] = float(z[0])


def _write_lidar(sensors, f, recs, owner, emission, to_origin=None, *, n=0) -> h5py.Group:
    """The captures' scans of LiDAR `n` (``lidar_NN``): their mounting `to_origin`
    (4x4; the first scan's)."""
    clouds = [recs[i].lidars[n] for i in owner]
    first = clouds[0]
    top = max(1, max(len(c) for c in clouds))
    at = first.to_sensor if to_origin is None else to_origin
    g = _sensor(sensors, lidar_name(n), "lidar", at)
    g.attrs.update(max_points=top, rate_hz=first.rate_hz, name=first.name)
    pts = np.full((len(clouds), top, 4), np.nan, np.float32)
    ring = np.full((len(clouds), top), -1, np.int16)
    when = np.full((len(clouds), top), np.nan, np.float32)
    for k, c in enumerate(clouds):
        pts[k, : len(c), :3], pts[k, : len(c), 3] = c.points_m, c.intensity
        if c.ring is not None:
            ring[k, : len(c)] = c.ring
        if c.time_s is not None:
            when[k, : len(c)] = c.time_s
    g.create_dataset("data/points", data=pts, chunks=(1, top, 4))
    g.create_dataset("data/point_counts", data=np.array([len(c) for c in clouds], np.int64))
    g.create_dataset("data/timestamps", data=emission).attrs["units"] = "s"
    ours = f.require_group(our_lidar(n))
    ours.create_dataset("ring", data=ring, chunks=(1, top))
    ours.create_dataset("time_s", data=when, chunks=(1, top)).attrs["units"] = "s"
    return g


def _write_array_extras(ours: h5py.Group, array: Array, name: str = "array") -> None:
    a = ours.create_group(name)
    a.attrs["name"] = array.name
    a.create_dataset("channels", data=array.channels)
    if array.grid_index is not None:
        a.create_dataset("grid_index", data=array.grid_index).attrs["pitch_m"] = array.pitch_m


def _write_recording_extras(g: h5py.Group, rec: Recording, checksum: bool) -> None:
    g.attrs.update(
        emission_index=rec.emission_index,
        speed_of_sound_m_s=rec.speed_of_sound_m_s,
        waveform=json.dumps(rec.waveform.to_dict()),
    )
    g.create_dataset("metadata", data=json.dumps(rec.metadata, default=_plain))
    if rec.truth is None:
        return
    t = g.create_group("truth")
    kw = {"fletcher32": checksum} if len(rec.truth) else {}
    for name, units in _TRUTH:
        data = getattr(rec.truth, name)
        if data is None:
            continue
        data = data.astype("S16") if name == "kind" else data
        if name == "emitter":
            data = np.array([n.encode("utf-8") for n in data.tolist()], dtype=bytes)
        data = data.astype(np.int16) if name == "order" else data
        data = data.astype(np.int32) if name == "object_index" else data
        data = data.astype(np.float32) if name in STORED_SEEN and name != "object_index" else data
        d = t.create_dataset(name, data=data, **kw)
        if units:
            d.attrs["units"] = units
    if rec.truth.object_index is not None:
        names = list(rec.truth.object_names)
        t.create_dataset("object_names", data=names, dtype=h5py.string_dtype("utf-8"))


def _plain(obj):
    if isinstance(obj, np.ndarray | np.generic):
        return obj.tolist()
    raise TypeError(f"metadata value of type {type(obj).__name__} is not JSON-serialisable")
