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
                                                               extent, recording index,
                                                               sensor, mount, emission
                                                               time, crosstalk,
                                                               emitters
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
                                                               re strongest, order,
                                                               ..., emitter
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
the frame named as the sonar (no ``/acousim/raw``...: a topic is declared only with
messages); ``/tf`` carries ``world`` -> ``acousim_body`` (the body's pose at each
firing) and ``/tf_static`` the fixed mounts ``acousim_body`` -> ``<sonar>``, once at
the bag's first stamp, offered latched (durability transient local, as ROS 2's
static broadcaster).  A reflector's ``emitter`` is the index into the info's
``emitters`` (the rig's sonars; one sensor: ``acousim_sensor``) of the sonar whose
call the path carries.

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
from acousim.viz.truth import own_sonar, truth_level_db
from processing.base import interrupt
from processing.base.atomic import TEMP_PREFIX
from processing.base.errors import InputError

__all__ = [
    "FRAME_BODY",
    "FRAME_SENSOR",
    "FRAME_WORLD",
    "TF_STATIC",
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
#: a rig's mounts (body -> sonar), once, latched (durability transient local)
TF_STATIC = ("/tf_static", "tf2_msgs/msg/TFMessage")
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
    "emitter",
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
    """The bag's topics, one message of each per recording, written into `bag`; a
    topic is declared with its first message (none without messages)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = _typestore()
    T = store.types
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        put = _Topics(w, store).put
        stamps = [recording_time_ns(r, i) for i, r in zip(indices, recordings)]
        mounts = _static_tf_msg(T, recordings, min(stamps, default=0))
        if mounts is not None:  # a rig: its mounts, once, latched
            put(TF_STATIC, mounts, min(stamps), latched=True)
        scene = _SceneTopics(w, store, recordings)
        scans = _lidar_writer(w, store, recordings)  # /acousim/lidar, with scans only

        for idx, ns, rec, imgs in zip(indices, stamps, recordings, images):
            interrupt.check()  # Ctrl-C: stop here (the temporary folder is removed)
            sonar = rec.metadata.get("sensor")  # a rig's recording: its sonar's name
            header = T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
                frame_id=FRAME_SENSOR if sonar is None else sonar,
            )
            m = o.method or drive_method(dict(imgs))
            img = imgs[m]
            raster = fan_raster(img, _fan_range(img), o.dynamic_range_db, o.fan_pixels)
            sensor, _ = peak_positions(rec, pk := img.peaks(o.threshold_db))
            info = _info_msg(T, rec, idx, m, raster, o.dynamic_range_db)
            for key, msg in (
                ("raw", _raw_msg(T, rec)),
                ("info", info),
                ("peaks", _cloud_msg(T, header, sensor, pk)),
                ("fan", _image_msg(T, header, raster.db)),
            ):
                put(sonar_topic(key, sonar), msg, ns)
            if sonar is None:
                put(TOPICS["tf"], _tf_msg(T, header, _pose(rec)), ns)
            else:  # the moving body only: its mounts are on /tf_static
                put(TOPICS["tf"], _body_tf_msg(T, header, rec.metadata), ns)
            scene.write(rec, header, ns)
            scans(rec, header, ns)


def sonar_topic(key: str, sonar: str | None) -> tuple[str, str]:
    """The topic and type of `key` (``raw``, ``info``, ``peaks``, ``fan``) for a
    recording of sonar `sonar` (``/acousim/<sonar>/<key>``; None: a single sensor's,
    ``/acousim/<key>``)."""
    topic, kind = TOPICS[key]
    return (topic if sonar is None else f"/acousim/{sonar}/{key}"), kind


class _Topics:
    """The bag's connections, each added with its topic's first message."""

    def __init__(self, writer, store) -> None:
        self.w, self.store, self.conns = writer, store, {}

    def put(self, topic: tuple[str, str], msg, stamp: int, latched: bool = False) -> None:
        """Write `msg` on `topic` (name, type) at `stamp` (ns); `latched`: offered as
        ROS 2 latches (durability transient local, :func:`latched_qos`)."""
        name, kind = topic
        if name not in self.conns:
            qos = latched_qos() if latched else None
            extra = {} if qos is None else {"offered_qos_profiles": qos}
            self.conns[name] = self.w.add_connection(name, kind, typestore=self.store, **extra)
        self.w.write(self.conns[name], stamp, self.store.serialize_cdr(msg, kind))


def latched_qos() -> list | None:
    """The QoS ROS 2 offers a latched topic such as ``/tf_static`` (reliable,
    durability transient local, keep last 1), as rosbags declares it; None when the
    installed rosbags does not take QoS profiles."""
    import inspect

    from rosbags.rosbag2 import Writer

    try:
        from rosbags.interfaces import (
            Qos,
            QosDurability,
            QosHistory,
            QosLiveliness,
            QosReliability,
            QosTime,
        )
    except ImportError:  # pragma: no cover - an older rosbags
        return None
    param = inspect.signature(Writer.add_connection).parameters.get("offered_qos_profiles")
    if param is None or isinstance(param.default, str):  # pragma: no cover - older rosbags
        return None
    never = QosTime(0, 0)  # rosbag2's "infinite" (the default)
    return [
        Qos(
            history=QosHistory.KEEP_LAST,
            depth=1,
            reliability=QosReliability.RELIABLE,
            durability=QosDurability.TRANSIENT_LOCAL,
            deadline=never,
            lifespan=never,
            liveliness=QosLiveliness.AUTOMATIC,
            liveliness_lease_duration=never,
            avoid_ros_namespace_conventions=False,
        )
    ]


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
        "emission_index": int(rec.emission_index),
        **_sonar_info(rec),
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


def _sonar_info(rec: P.Recording) -> dict:
    """Which sensor recorded, where it sits and what it heard: ``sensor`` (a rig's
    sonar, else None), ``frame_id``, ``emission_time_s`` (its call's start, s, the
    body's clock; None unknown), ``mount`` (a rig's sonar in the body frame:
    ``position_m``, ``rotation_deg`` roll, pitch, yaw), ``crosstalk`` (the other
    calls in the recording: sonar, measurement, emission time and delay after this
    call, s, and their number of paths), ``emitters`` (what the reflectors'
    ``emitter`` indexes) and ``object_names`` (what their ``object`` indexes)."""
    meta = rec.metadata
    sonar = meta.get("sensor")
    pose = rec.provenance.pose
    t = meta.get("emission_time_s", None if pose is None else pose.time_s)
    return {
        "sensor": sonar,
        "frame_id": FRAME_SENSOR if sonar is None else sonar,
        "emission_time_s": t,
        "mount": meta.get("mount"),
        "crosstalk": list(meta.get("crosstalk", [])),
        "emitters": emitter_names(rec),
        "object_names": list(rec.truth.object_names) if rec.truth is not None else [],
    }


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


def _body_tf_msg(T, header, meta: dict):
    """A rig's moving frame at a firing: world -> body (metadata ``body_pose``)."""
    b = meta["body_pose"]
    body = Pose.degrees(b["position_m"], b["yaw_deg"], b["pitch_deg"], b["roll_deg"])
    tf = _transform(T, header.stamp, FRAME_WORLD, FRAME_BODY, body.rotation, body.position_m)
    return T["tf2_msgs/msg/TFMessage"](transforms=[tf])


def _static_tf_msg(T, recordings: Sequence[P.Recording], stamp_ns: int):
    """A rig's fixed extrinsics: body -> each sonar (its mount, metadata ``mount``;
    the first recording of each sonar), one TFMessage stamped `stamp_ns`; None for
    recordings of no rig."""
    mounts: dict[str, Mount] = {}
    for rec in recordings:
        sonar = rec.metadata.get("sensor")
        if sonar is not None and sonar not in mounts:
            m = rec.metadata["mount"]
            mounts[sonar] = Mount.degrees(m["position_m"], m["rotation_deg"])
    if not mounts:
        return None
    stamp = T["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    return T["tf2_msgs/msg/TFMessage"](
        transforms=[
            _transform(T, stamp, FRAME_BODY, sonar, m.rotation, m.position_m)
            for sonar, m in mounts.items()
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
    """The traced echo paths (the sonar's own direct path left out; a rig's other
    sonars' calls heard straight kept: crosstalk, shown in its image) as a PointCloud2 in the
    sensor frame: x, y, z their last reflection (m), level_db (re the strongest
    echo), order (number of reflections), apparent_x/y/z where the sensor sees them
    (m), delay_s their two-way delay at the array centre (s) and object (the index
    into the recording's ``truth.object_names``, -1 none) and emitter (whose call
    the path carries: the index into :func:`emitter_names`, the info's
    ``emitters``); NaN where a recording carries no apparent positions (a file
    written before they existed)."""
    t = rec.truth
    if t is None or not len(t):
        table = np.zeros((0, len(REFLECTOR_FIELDS)), "<f4")
    else:
        lvl = truth_level_db(t, own_sonar(rec))
        keep = np.isfinite(lvl)
        n = int(keep.sum())
        seen = (
            [t.apparent_position_sensor_m[keep], t.delay_s[keep, None]]
            if t.has_apparent
            else [np.full((n, 4), np.nan)]
        )
        obj = t.object_index[keep] if t.object_index is not None else np.full(n, -1)
        emitter = emitter_index(rec)[keep]
        table = np.column_stack(
            [t.position_sensor_m[keep], lvl[keep, None], t.order[keep, None], *seen, obj, emitter]
        ).astype("<f4")
    return _point_cloud(T, header, table, REFLECTOR_FIELDS)


def emitter_names(rec: P.Recording) -> list[str]:
    """The sonars whose calls a recording may hear, the names the reflectors'
    ``emitter`` field indexes (``/acousim/.../info`` → ``emitters``): a rig's sonars
    in the rig's order (metadata ``rig``), else the sensor's own frame."""
    meta = rec.metadata
    if meta.get("rig"):
        return [str(n) for n in meta["rig"]]
    return [str(meta.get("sensor") or FRAME_SENSOR)]


def emitter_index(rec: P.Recording) -> np.ndarray:
    """(N,) int: for each path of the recording's truth, the index into
    :func:`emitter_names` of the sonar whose call it carries (the recording's own
    where the truth names none; -1 a name not in the list)."""
    t = rec.truth
    names = emitter_names(rec)
    own = names.index(rec.metadata.get("sensor") or names[0])
    n = 0 if t is None else len(t.order)
    if t is None or t.emitter is None:
        return np.full(n, own)
    lookup = {name: i for i, name in enumerate(names)}
    return np.array([lookup.get(str(e), -1) for e in t.emitter], dtype=int).reshape(n)
