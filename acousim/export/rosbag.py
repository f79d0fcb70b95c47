"""ROS 2 bags (rosbag2, MCAP storage) of recordings and their images, written with
the pure-Python ``rosbags`` library (no ROS installation needed).

Topics (one message each per recording, all stamped with the recording's time;
see docs/export.md for the full layout):

============================  ===============================  =====================
topic                         type                             content
============================  ===============================  =====================
``/acousim/raw``              ``std_msgs/msg/Float32MultiArray``  samples (M, T), row
                                                               major: dim 0
                                                               "microphone" (M),
                                                               dim 1 "sample" (T)
``/acousim/info``             ``std_msgs/msg/String``          JSON: sample rate,
                                                               speed of sound, array
                                                               geometry, call, fan
                                                               extent, recording index
``/acousim/peaks``            ``sensor_msgs/msg/PointCloud2``  image peaks in the
                                                               sensor frame: float32
                                                               x, y, z (m), level_db,
                                                               range_m
``/acousim/fan``              ``sensor_msgs/msg/Image``        top view, ``32FC1``, dB
                                                               re strongest; NaN = no
                                                               data; row 0 = farthest
``/tf``                       ``tf2_msgs/msg/TFMessage``       world -> sensor pose
``/clock``                    ``rosgraph_msgs/msg/Clock``      the recording's time
                                                               (for use_sim_time)
``/acousim/scene``            ``visualization_msgs/msg/``      the scene's meshes in
                              ``MarkerArray``                  the world frame: id 0
                                                               still meshes (first
                                                               stamp), id 1 moving
                                                               ones (every stamp)
``/acousim/reflectors``       ``sensor_msgs/msg/PointCloud2``  traced reflectors
                                                               (simulations) in the
                                                               sensor frame: float32
                                                               x, y, z (m), level_db
                                                               re strongest, order
``/acousim/lidar``            ``sensor_msgs/msg/PointCloud2``  the LiDAR scan (only
                                                               recordings with one;
                                                               ``lidar_cloud``); a
                                                               rig's other LiDARs:
                                                               ``/acousim/lidar_01``...
============================  ===============================  =====================

``/acousim/scene`` is written when the recording's scene file can be read,
``/acousim/reflectors`` when the recordings carry ground truth.

A rig's recordings (``metadata["sensor"]``, :mod:`acousim.rig`) each go to their
sonar's own topic set, ``/acousim/<sonar>/raw``, ``info``, ``peaks`` and ``fan``, in
the frame named as the sonar, and ``/tf`` carries the tree ``world`` ->
``acousim_body`` (the body's pose at the firing) -> ``<sonar>`` (its mount).

Time stamps: a real recording's ``timestamp`` (Unix time), else the pose's
``time_s`` of a simulated trajectory, else the recording's index x 0.1 s.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import processing as P
from acousim.export.lidar_cloud import LIDAR_TOPIC, lidar_cloud_msg, lidar_topic
from acousim.imaging.run import (
    PEAK_THRESHOLD_DB,
    _moving_triangles,
    _pose,
    _scene,
    _scene_triangles,
    drive_method,
    peak_positions,
)
from acousim.scene.pose import Pose
from acousim.scene.rig import Mount
from acousim.viz.fan import DYNAMIC_RANGE_DB, fan_raster
from acousim.viz.truth import truth_level_db
from processing.base import interrupt
from processing.base.atomic import TEMP_PREFIX
from processing.base.errors import InputError

__all__ = [
    "FRAME_BODY",
    "FRAME_SENSOR",
    "FRAME_WORLD",
    "TOPICS",
    "write_rosbag",
    "recording_time_ns",
]

FRAME_WORLD = "world"
FRAME_SENSOR = "acousim_sensor"
#: a rig's body frame (the TF tree world -> body -> each sonar, named as the sonar)
FRAME_BODY = "acousim_body"
TOPICS = {
    "raw": ("/acousim/raw", "std_msgs/msg/Float32MultiArray"),
    "info": ("/acousim/info", "std_msgs/msg/String"),
    "peaks": ("/acousim/peaks", "sensor_msgs/msg/PointCloud2"),
    "fan": ("/acousim/fan", "sensor_msgs/msg/Image"),
    "tf": ("/tf", "tf2_msgs/msg/TFMessage"),
}
PEAK_FIELDS = ("x", "y", "z", "level_db", "range_m")
#: optional topics: written when the recordings have them (see the module docstring)
SCENE_TOPICS = {
    "clock": ("/clock", "rosgraph_msgs/msg/Clock"),
    "scene": ("/acousim/scene", "visualization_msgs/msg/MarkerArray"),
    "reflectors": ("/acousim/reflectors", "sensor_msgs/msg/PointCloud2"),
}
REFLECTOR_FIELDS = (
    "x",
    "y",
    "z",
    "level_db",
    "order",
    "apparent_x",
    "apparent_y",
    "apparent_z",
    "delay_s",
    "object",
)
SCENE_COLOR = (0.7, 0.7, 0.75, 0.5)  # RGBA of the still meshes; moving ones are orange
MOVING_COLOR = (1.0, 0.55, 0.1, 0.7)


def _typestore():
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("ROS 2 bags need rosbags: pip install 'acousim[ros]'") from exc
    return get_typestore(Stores.ROS2_HUMBLE)


def recording_time_ns(rec: P.Recording, index: int) -> int:
    """The stamp of a recording (ns): its Unix timestamp (real), its pose's time
    (simulated trajectory), else index x 0.1 s."""
    prov = rec.provenance
    if prov.timestamp_s is not None:
        t = prov.timestamp_s
    elif prov.pose is not None:
        t = prov.pose.time_s
    else:
        t = 0.1 * index
    return int(round(t * 1e9))


def write_rosbag(
    path: str | Path,
    recordings: Sequence[P.Recording],
    images: Sequence[Mapping[str, P.Image]],
    indices: Sequence[int] | None = None,
    *,
    method: str | None = None,
    threshold_db: float = PEAK_THRESHOLD_DB,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    fan_pixels: int = 400,
) -> Path:
    """Write a rosbag2 folder (MCAP storage) at `path`, which must not exist.

    The bag is written into a temporary folder beside `path` and renamed when
    complete: an error or Ctrl-C leaves nothing behind.

    method : the image published as peaks and fan (default: the sharpest imaged,
        as in the pictures).
    threshold_db : peaks within this of the image's strongest cell.
    dynamic_range_db : of the fan image (levels below -dynamic_range_db are floored).
    """
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} exists already; a bag is never overwritten")
    several = [
        i for i, r in zip(indices or range(len(recordings)), recordings) if r.samples.ndim != 2
    ]
    if several:
        raise InputError(
            "holds several measurements (K, M, T); a bag takes one per recording",
            key="recording",
            value=several[0],
        )
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    parent = path.parent if str(path.parent) else Path(".")
    work = Path(tempfile.mkdtemp(prefix=TEMP_PREFIX, suffix=f"-{path.name}", dir=parent))
    try:
        bag = work / path.name
        options = _BagOptions(method, threshold_db, dynamic_range_db, fan_pixels)
        _write_bag(bag, recordings, images, indices, options)
        _rename_unless_interrupted(bag, path)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return path


@dataclass(frozen=True)
class _BagOptions:
    """What :func:`write_rosbag` publishes of each recording (see its parameters)."""

    method: str | None
    threshold_db: float
    dynamic_range_db: float
    fan_pixels: int


def _write_bag(bag: Path, recordings, images, indices: list[int], o: _BagOptions) -> None:
    """The bag's topics, one message of each per recording, written into `bag`."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = _typestore()
    T = store.types
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {
            k: w.add_connection(topic, msgtype, typestore=store)
            for k, (topic, msgtype) in TOPICS.items()
        }

        def put(key: str, msg, stamp: int, sensor: str | None = None) -> None:
            topic, kind = TOPICS[key]
            if sensor is not None and key != "tf":  # a rig's sonar: its own topic set
                topic = f"/acousim/{sensor}/{key}"
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, kind, typestore=store)
                key = topic
            w.write(conns[key], stamp, store.serialize_cdr(msg, kind))

        scene = _SceneTopics(w, store, recordings)
        scans = _lidar_writer(w, store, recordings)  # /acousim/lidar, with scans only

        for idx, rec, imgs in zip(indices, recordings, images):
            interrupt.check()  # Ctrl-C: stop here (the temporary folder is removed)
            ns = recording_time_ns(rec, idx)
            sonar = rec.metadata.get("sensor")  # a rig's recording: its sonar's name
            header = T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
                frame_id=FRAME_SENSOR if sonar is None else sonar,
            )
            m = o.method or drive_method(dict(imgs))
            img = imgs[m]
            put("raw", _raw_msg(T, rec), ns, sonar)
            raster = fan_raster(img, _fan_range(img), o.dynamic_range_db, o.fan_pixels)
            put("info", _info_msg(T, rec, idx, m, raster, o.dynamic_range_db), ns, sonar)
            sensor, _ = peak_positions(rec, pk := img.peaks(o.threshold_db))
            put("peaks", _cloud_msg(T, header, sensor, pk), ns, sonar)
            put("fan", _image_msg(T, header, raster.db), ns, sonar)
            if sonar is None:
                put("tf", _tf_msg(T, header, _pose(rec)), ns)
            else:
                put("tf", _rig_tf_msg(T, header, rec.metadata, sonar), ns)
            scene.write(rec, header, ns)
            scans(rec, header, ns)


def _rename_unless_interrupted(bag: Path, path: Path) -> None:
    """The finished bag renamed into place, unless Ctrl-C came (SIGINT held back from
    the check to the rename, as processing.base.atomic does for files)."""
    import signal

    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        interrupt.check()
        bag.rename(path)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _lidar_writer(w, store, recordings):
    """A function writing a recording's LiDAR scans (:mod:`acousim.export.lidar_cloud`)
    to ``/acousim/lidar`` (a rig's other LiDARs: ``/acousim/lidar_01``, ...); a topic
    exists only when some recording has its scan."""
    n_lidars = max(len(r.lidars) for r in recordings)
    conns = [
        w.add_connection(lidar_topic(n), LIDAR_TOPIC[1], typestore=store) for n in range(n_lidars)
    ]

    def write(rec: P.Recording, header, ns: int) -> None:
        for conn, scan in zip(conns, rec.lidars):
            msg = lidar_cloud_msg(store.types, header, scan)
            w.write(conn, ns, store.serialize_cdr(msg, LIDAR_TOPIC[1]))

    return write


def _fan_range(img: P.Image) -> float:
    return float(img.range_m.max()) if img.range_m.size else 1.0


def _raw_msg(T, rec: P.Recording):
    M, N = rec.samples.shape
    dim = T["std_msgs/msg/MultiArrayDimension"]
    layout = T["std_msgs/msg/MultiArrayLayout"](
        dim=[dim(label="microphone", size=M, stride=M * N), dim(label="sample", size=N, stride=N)],
        data_offset=0,
    )
    data = np.ascontiguousarray(rec.samples, dtype=np.float32).ravel()
    return T["std_msgs/msg/Float32MultiArray"](layout=layout, data=data)


def _info_msg(T, rec: P.Recording, index: int, method: str, raster, dynamic_range_db: float):
    wf = rec.waveform
    info = {
        "recording": index,
        "scene": rec.provenance.scene,
        "provenance": rec.provenance.kind,  # simulated, real or emulated
        "simulated": rec.provenance.simulated,
        "sample_rate_hz": rec.sample_rate_hz,
        "speed_of_sound_m_s": rec.speed_of_sound_m_s,
        "array": rec.array.name,
        "mic_positions_m": np.asarray(rec.array.positions_m).tolist(),
        "emitter_m": np.asarray(rec.array.emitter_m).tolist(),
        "call": {
            "kind": wf.kind,
            "f_start_hz": wf.f_start_hz,
            "f_end_hz": wf.f_end_hz,
            "duration_s": wf.duration_s,
        },
        "raw": "std_msgs/Float32MultiArray (microphone, sample), row major, float32",
        "image_method": method,
        "fan": {
            "encoding": "32FC1 level in dB re the strongest cell; NaN = no data",
            "dynamic_range_db": dynamic_range_db,
            "rows": "row 0 = farthest x (top of the picture), x decreasing downwards",
            "columns": "column 0 = largest y (left), y decreasing to the right",
            "extent_m": dict(
                zip(("y_left", "y_right", "x_near", "x_far"), map(float, raster.extent))
            ),
        },
    }
    return T["std_msgs/msg/String"](data=json.dumps(info))


def _cloud_msg(T, header, points_sensor: np.ndarray, pk: P.Peaks):
    table = np.column_stack(
        [points_sensor.reshape(-1, 3), pk.level_db.reshape(-1, 1), pk.range_m.reshape(-1, 1)]
    ).astype("<f4")
    return _point_cloud(T, header, table, PEAK_FIELDS)


def _point_cloud(T, header, table: np.ndarray, names) -> object:
    """A PointCloud2 of the rows of `table` (N, F) little-endian float32, one field
    per column named by `names` (F)."""
    field = T["sensor_msgs/msg/PointField"]
    fields = [field(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate(names)]
    n, step = len(table), 4 * len(names)
    return T["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=1,
        width=n,
        fields=fields,
        is_bigendian=False,
        point_step=step,
        row_step=step * n,
        data=np.frombuffer(table.tobytes(), np.uint8),
        is_dense=True,
    )


def _image_msg(T, header, db: np.ndarray):
    top_row_first = np.ascontiguousarray(db[::-1], dtype="<f4")  # raster row 0 is nearest
    h, w = top_row_first.shape
    return T["sensor_msgs/msg/Image"](
        header=header,
        height=h,
        width=w,
        encoding="32FC1",
        is_bigendian=False,
        step=4 * w,
        data=np.frombuffer(top_row_first.tobytes(), np.uint8),
    )


def _tf_msg(T, header, pose):
    """The sensor's TF at a recording: world -> sensor (its pose)."""
    tf = _transform(T, header.stamp, FRAME_WORLD, FRAME_SENSOR, pose.rotation, pose.position_m)
    return T["tf2_msgs/msg/TFMessage"](transforms=[tf])


def _transform(T, stamp, parent: str, child: str, rotation: np.ndarray, position):
    """A geometry_msgs TransformStamped parent -> child (rotation (3, 3) child ->
    parent, position (3,) m of the child's origin in the parent frame)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(rotation).as_quat()
    p = np.asarray(position, float)
    return T["geometry_msgs/msg/TransformStamped"](
        header=T["std_msgs/msg/Header"](stamp=stamp, frame_id=parent),
        child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        ),
    )


def _rig_tf_msg(T, header, meta: dict, sonar: str):
    """A rig's TF tree at a firing: world -> body (the body's pose) and body -> the
    sonar (its mount; metadata ``body_pose`` and ``mount``)."""
    b = meta["body_pose"]
    body = Pose.degrees(b["position_m"], b["yaw_deg"], b["pitch_deg"], b["roll_deg"])
    mount = Mount.degrees(meta["mount"]["position_m"], meta["mount"]["rotation_deg"])
    return T["tf2_msgs/msg/TFMessage"](
        transforms=[
            _transform(T, header.stamp, FRAME_WORLD, FRAME_BODY, body.rotation, body.position_m),
            _transform(T, header.stamp, FRAME_BODY, sonar, mount.rotation, mount.position_m),
        ]
    )


class _SceneTopics:
    """/clock, the scene's meshes as markers and the traced reflectors (see the module
    docstring): what a viewer needs to show the scene beside the images."""

    def __init__(self, writer, store, recordings: Sequence[P.Recording]) -> None:
        self.w, self.store, self.T = writer, store, store.types
        self.scene = _scene(recordings[0]) if recordings else None
        self.still = _scene_triangles(self.scene)
        self.moving = self.scene is not None and any(m.moving for m in self.scene.meshes)
        keys = ["clock"]
        if self.still is not None or self.moving:
            keys.append("scene")
        if any(r.truth is not None and len(r.truth) for r in recordings):
            keys.append("reflectors")
        self.conns = {k: writer.add_connection(*SCENE_TOPICS[k], typestore=store) for k in keys}
        self.first = True

    def _put(self, key: str, msg, stamp: int) -> None:
        self.w.write(self.conns[key], stamp, self.store.serialize_cdr(msg, SCENE_TOPICS[key][1]))

    def write(self, rec: P.Recording, header, ns: int) -> None:
        self._put("clock", self.T["rosgraph_msgs/msg/Clock"](clock=header.stamp), ns)
        if "scene" in self.conns:
            markers = []
            if self.first and self.still is not None:
                markers.append(_mesh_marker(self.T, header, 0, self.still, SCENE_COLOR))
            if self.moving:
                tri = _moving_triangles(self.scene, rec)
                markers.append(_mesh_marker(self.T, header, 1, tri, MOVING_COLOR))
            if markers:
                self._put("scene", self.T["visualization_msgs/msg/MarkerArray"](markers), ns)
        if "reflectors" in self.conns:
            self._put("reflectors", _reflector_msg(self.T, header, rec), ns)
        self.first = False


def _mesh_marker(T, header, marker_id: int, triangles: np.ndarray, rgba):
    """A TRIANGLE_LIST marker of triangles (F, 3, 3) in the world frame, kept until
    replaced (lifetime 0)."""
    M = T["visualization_msgs/msg/Marker"]
    point = T["geometry_msgs/msg/Point"]
    pts = [point(x=float(x), y=float(y), z=float(z)) for x, y, z in triangles.reshape(-1, 3)]
    return M(
        header=T["std_msgs/msg/Header"](stamp=header.stamp, frame_id=FRAME_WORLD),
        ns="acousim_scene",
        id=marker_id,
        type=M.TRIANGLE_LIST,
        action=M.ADD,
        pose=T["geometry_msgs/msg/Pose"](
            position=point(x=0.0, y=0.0, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
        scale=T["geometry_msgs/msg/Vector3"](x=1.0, y=1.0, z=1.0),
        color=T["std_msgs/msg/ColorRGBA"](*map(float, rgba)),
        lifetime=T["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
        frame_locked=False,
        points=pts,
        colors=[],
        texture_resource="",
        texture=T["sensor_msgs/msg/CompressedImage"](
            header=T["std_msgs/msg/Header"](stamp=header.stamp, frame_id=FRAME_WORLD),
            format="",
            data=np.zeros(0, np.uint8),
        ),
        uv_coordinates=[],
        text="",
        mesh_resource="",
        mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
        mesh_use_embedded_materials=False,
    )


def _reflector_msg(T, header, rec: P.Recording):
    """The traced echo paths (the direct path left out) as a PointCloud2 in the
    sensor frame: x, y, z their last reflection (m), level_db (re the strongest
    echo), order (number of reflections), apparent_x/y/z where the sensor sees them
    (m), delay_s their two-way delay at the array centre (s) and object (the index
    into the recording's ``truth.object_names``, -1 none); NaN where a recording
    carries no apparent positions (a file written before they existed)."""
    t = rec.truth
    if t is None or not len(t):
        table = np.zeros((0, len(REFLECTOR_FIELDS)), "<f4")
    else:
        lvl = truth_level_db(t)
        keep = np.isfinite(lvl)
        n = int(keep.sum())
        seen = (
            [t.apparent_position_sensor_m[keep], t.delay_s[keep, None]]
            if t.has_apparent
            else [np.full((n, 4), np.nan)]
        )
        obj = t.object_index[keep] if t.object_index is not None else np.full(n, -1)
        table = np.column_stack(
            [t.position_sensor_m[keep], lvl[keep, None], t.order[keep, None], *seen, obj]
        ).astype("<f4")
    return _point_cloud(T, header, table, REFLECTOR_FIELDS)
