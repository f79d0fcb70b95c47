"""A rig's ROS 2 bag read back with rosbags alone: one topic set per sonar and only
topics with messages, the moving body on /tf and the fixed mounts latched on
/tf_static, each sonar's info (name, mount, emission time, crosstalk) and the
emitter of every traced reflector.  References: the mounts and firing times given
here, the rotations written out by hand, and the mirror-image formula for the wall
echo of one sonar's call heard by the other."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import processing as P
from acousim.cli import main
from acousim.rig import RigSimulator
from acousim.scene import Pose
from acousim.scene.rig import Firing, Mount, Rig, RigSonar
from tests.acousim.test_rig import WALL_X, mirror, wall_scene

BODY_XYZ, BODY_YAW = np.array([0.5, 0.3, 0.1]), np.deg2rad(20.0)
# the sonars in the body frame: position (m), roll, pitch, yaw (deg); fired 5 ms apart
MOUNTS = {
    "left": ((0.0, 0.25, 0.0), (0.0, 0.0, 0.0)),
    "right": ((0.1, -0.25, 0.05), (4.0, -6.0, -10.0)),
}
TIMES = {"left": 0.0, "right": 0.005}


def rz(a):
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def ry(a):
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def rx(a):
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def mount_rotation(name):
    """Sensor -> body: yaw about z, then pitch about y, then roll about x."""
    roll, pitch, yaw = np.deg2rad(MOUNTS[name][1])
    return rz(yaw) @ ry(pitch) @ rx(roll)


def quat_matrix(q):
    """The rotation of a unit quaternion (x, y, z, w), the textbook formula."""
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def translation(tf):
    v = tf.transform.translation
    return np.array([v.x, v.y, v.z])


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """The exported bag of one firing of each sonar: its connections by topic, its
    messages by topic ((connection, stamp ns, message) each) and its folder."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    d = tmp_path_factory.mktemp("rigbag")
    scene = wall_scene(d)
    sonars = tuple(
        RigSonar(n, scene.sensor, Mount.degrees(*MOUNTS[n]), Firing(times_s=(TIMES[n],)))
        for n in MOUNTS
    )
    body = Pose(BODY_XYZ, BODY_YAW)
    scene = dataclasses.replace(scene, rig=Rig(sonars, poses=(body,)))
    P.save_recordings(d / "r.h5", list(RigSimulator(scene).run().recordings))
    out = d / "bag"
    assert main(["export", str(d / "r.h5"), "--out", str(out), "--method", "das"]) == 0
    msgs: dict = {}
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        declared = {c.topic: c for c in reader.connections}
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            msgs.setdefault(conn.topic, []).append((conn, stamp, msg))
    return declared, msgs, out


def test_only_topics_with_messages_one_set_per_sonar(bag):
    declared, msgs, _ = bag
    assert set(declared) == set(msgs)  # nothing declared without a message
    for name in MOUNTS:
        for kind in ("raw", "info", "peaks", "fan"):
            assert len(msgs[f"/acousim/{name}/{kind}"]) == 1, (name, kind)
        assert msgs[f"/acousim/{name}/peaks"][0][2].header.frame_id == name
    for kind in ("raw", "info", "peaks", "fan"):
        assert f"/acousim/{kind}" not in declared  # a single sensor's topics: not a rig's


def test_mounts_latched_on_tf_static_and_the_body_on_tf(bag):
    from rosbags.interfaces import QosDurability

    declared, msgs, _ = bag
    ((conn, stamp, static),) = msgs["/tf_static"]  # once, at the bag's first stamp
    assert stamp == min(s for m in msgs.values() for _, s, _ in m) == 0
    (qos,) = conn.ext.offered_qos_profiles
    assert qos.durability == QosDurability.TRANSIENT_LOCAL and qos.depth == 1
    assert {t.child_frame_id for t in static.transforms} == set(MOUNTS)
    for t in static.transforms:
        name = t.child_frame_id
        assert t.header.frame_id == "acousim_body"
        np.testing.assert_allclose(translation(t), MOUNTS[name][0], atol=1e-12)
        np.testing.assert_allclose(
            quat_matrix(t.transform.rotation), mount_rotation(name), atol=1e-12
        )
    # /tf: the moving body only, at each firing
    tfs = msgs["/tf"]
    assert [s for _, s, _ in tfs] == [round(TIMES[n] * 1e9) for n in ("left", "right")]
    for _, _, tf in tfs:
        (t,) = tf.transforms
        assert (t.header.frame_id, t.child_frame_id) == ("world", "acousim_body")
        np.testing.assert_allclose(translation(t), BODY_XYZ, atol=1e-12)
        np.testing.assert_allclose(quat_matrix(t.transform.rotation), rz(BODY_YAW), atol=1e-12)


def test_each_sonars_info_names_it_its_mount_emission_and_crosstalk(bag):
    _, msgs, _ = bag
    for name, other in (("left", "right"), ("right", "left")):
        ((_, _, msg),) = msgs[f"/acousim/{name}/info"]
        info = json.loads(msg.data)
        assert info["sensor"] == info["frame_id"] == name
        assert info["mount"]["position_m"] == pytest.approx(MOUNTS[name][0], abs=1e-12)
        assert info["mount"]["rotation_deg"] == pytest.approx(MOUNTS[name][1], abs=1e-9)
        assert info["emission_time_s"] == pytest.approx(TIMES[name], abs=1e-15)
        assert info["emitters"] == ["left", "right"]
        (heard,) = info["crosstalk"]  # the other's call, 5 ms after or before its own
        assert heard["sensor"] == other
        assert heard["emission_time_s"] == pytest.approx(TIMES[other], abs=1e-15)
        assert heard["delay_s"] == pytest.approx(TIMES[other] - TIMES[name], abs=1e-15)


def test_each_reflector_names_the_sonar_whose_call_it_carries(bag):
    _, msgs, _ = bag
    body = rz(BODY_YAW)
    world = {n: BODY_XYZ + body @ np.array(MOUNTS[n][0]) for n in MOUNTS}  # sonar origins
    for k, (name, other) in enumerate((("left", "right"), ("right", "left"))):
        _, _, cloud = msgs["/acousim/reflectors"][k]
        assert cloud.header.frame_id == name
        fields = [f.name for f in cloud.fields]
        assert fields[-1] == "emitter" and cloud.point_step == 4 * len(fields)
        table = np.frombuffer(bytes(cloud.data), "<f4").reshape(cloud.width, len(fields))
        col = dict(zip(fields, table.T))
        emitters = sorted(set(col["emitter"].tolist()))
        assert emitters == [0.0, 1.0]  # its own call and the other's
        R = body @ mount_rotation(name)  # this sonar's frame -> world
        for emitter, src in ((name, name), (other, other)):
            index = ["left", "right"].index(emitter)
            wall = (col["emitter"] == index) & (col["order"] == 1)
            assert wall.sum() == 1, (name, emitter)
            # the wall's reflection point: where the line from the emitter's image to
            # this sonar's array centre crosses the wall's plane
            e, m = mirror(world[src]), world[name]
            s = (WALL_X - e[0]) / (m[0] - e[0])
            expected = R.T @ (e + s * (m - e) - world[name])
            got = np.array([col[c][wall][0] for c in ("x", "y", "z")])
            np.testing.assert_allclose(got, expected, atol=1e-5)


def test_info_counts_a_rig_bags_recordings_from_its_sonars_info_topics(bag):
    from acousim.dataset.info import describe

    lines = describe(bag[2])
    assert lines[1] == "  recordings: 2 simulated"
    assert "  /tf_static: tf2_msgs/msg/TFMessage, 1 message(s)" in lines


def test_info_prints_each_firings_yaw_pitch_and_roll(bag):
    """Sonar right in the world: the body's 20 deg yaw after its mount's yaw -10,
    pitch -6, roll 4 (the same axis for both yaws): yaw 10, pitch -6, roll 4."""
    from acousim.dataset.info import describe

    lines = describe(bag[2].parent / "r.h5")
    (right,) = [line for line in lines if "sonar 'right' fired at 0.005 s" in line]
    assert "yaw 10.0° pitch -6.0° roll 4.0°" in right
