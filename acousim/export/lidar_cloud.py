"""LiDAR scans as ``sensor_msgs/msg/PointCloud2`` (the ROS 2 bag's ``/acousim/lidar``).

One message per recording that carries a scan (:attr:`processing.Recording.lidar`),
in the sonar's frame (``acousim_sensor``: the scan's points moved by its mounting),
with the fields of Velodyne's ROS driver: ``x``, ``y``, ``z``, ``intensity``
(float32; m, and 0..1), ``time`` (float32, s after the scan started) and ``ring``
(uint16, the channel, 0 the lowest beam).
"""

from __future__ import annotations

import numpy as np

import processing as P

__all__ = ["LIDAR_TOPIC", "LIDAR_FIELDS", "lidar_cloud_msg", "lidar_topic"]

LIDAR_TOPIC = ("/acousim/lidar", "sensor_msgs/msg/PointCloud2")


def lidar_topic(n: int) -> str:
    """LiDAR n's topic: ``/acousim/lidar`` (the first), then a rig's others'
    ``/acousim/lidar_01``, ``/acousim/lidar_02``, ..."""
    return LIDAR_TOPIC[0] if n == 0 else f"{LIDAR_TOPIC[0]}_{n:02d}"


#: (name, offset, PointField datatype, numpy type): 7 = FLOAT32, 4 = UINT16
LIDAR_FIELDS = (
    ("x", 0, 7, "<f4"),
    ("y", 4, 7, "<f4"),
    ("z", 8, 7, "<f4"),
    ("intensity", 12, 7, "<f4"),
    ("time", 16, 7, "<f4"),
    ("ring", 20, 4, "<u2"),
)
POINT_STEP = 24  # 22 bytes of fields, padded to a multiple of 4


def lidar_cloud_msg(T, header, scan: P.PointCloud):
    """The PointCloud2 of one scan (`T`: the rosbags type store's types)."""
    dtype = np.dtype(
        {
            "names": [f[0] for f in LIDAR_FIELDS],
            "formats": [f[3] for f in LIDAR_FIELDS],
            "offsets": [f[1] for f in LIDAR_FIELDS],
            "itemsize": POINT_STEP,
        }
    )
    n = len(scan)
    table = np.zeros(n, dtype)
    xyz = scan.in_sensor()
    for i, axis in enumerate("xyz"):
        table[axis] = xyz[:, i]
    table["intensity"] = scan.intensity
    table["time"] = scan.time_s if scan.time_s is not None else 0.0
    table["ring"] = scan.ring if scan.ring is not None else 0
    field = T["sensor_msgs/msg/PointField"]
    return T["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=1,
        width=n,
        fields=[field(name=a, offset=o, datatype=d, count=1) for a, o, d, _ in LIDAR_FIELDS],
        is_bigendian=False,
        point_step=POINT_STEP,
        row_step=POINT_STEP * n,
        data=np.frombuffer(table.tobytes(), np.uint8),
        is_dense=True,
    )
