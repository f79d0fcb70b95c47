"""A rig of sonars on one body: the bistatic paths between them (crosstalk), their
firing schedule, the scene file's rig tables.  References: the mirror-image formula,
straight-line delays and the bistatic Doppler formula, written here."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.signal
import trimesh

from acousim import Simulator
from acousim.rig import RigSimulator
from acousim.scene import Pose, Trajectory, load_scene, parse_scene
from acousim.scene.rig import Firing, Mount, Rig, RigSonar
from acousim.trace.tracer import Tracer
from tests import REPO

WALL_X = 2.0  # the wall's face: the plane x = 2 m
LEFT, RIGHT = np.array([0.0, 0.25, 0.0]), np.array([0.0, -0.25, 0.0])  # 0.5 m apart


def wall_scene(tmp_path, max_range_m=3.0):
    """A rigid wall (reflection 1, no diffuse part) 2 m ahead of the body, facing it;
    no air absorption, no diffraction (the wall's far edges are beyond the range)."""
    wall = trimesh.creation.box(extents=(0.1, 20.0, 20.0))
    wall.apply_translation([WALL_X + 0.05, 0, 0])
    wall.export(tmp_path / "wall.obj", digits=12)
    return parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": True},
            "simulation": {
                "max_range_m": max_range_m,
                "diffraction": {"enabled": False},
                "absorption": False,
            },
            "materials": [{"name": "m", "reflection": 1.0, "diffuse": 0.0}],
            "meshes": [{"file": "wall.obj", "material": "m"}],
        },
        base_dir=tmp_path,
    )


def two_sonars(scene, times=((0.0,), (0.005,)), motion=None, crosstalk=True):
    """`scene` with a rig of two sonars facing +x, 0.5 m apart along y, fired at
    `times` (s, each a tuple)."""
    s = scene.sensor
    rig = Rig(
        sonars=(
            RigSonar("left", s, Mount(LEFT), Firing(times_s=times[0])),
            RigSonar("right", s, Mount(RIGHT), Firing(times_s=times[1])),
        ),
        poses=(Pose(np.zeros(3)),) if motion is None else (motion.pose(0.0),),
        motion=motion,
        crosstalk=crosstalk,
    )
    return dataclasses.replace(scene, rig=rig)


def mirror(p):
    """The image of points (..., 3) in the wall's plane."""
    q = np.array(p, float)
    q[..., 0] = 2 * WALL_X - q[..., 0]
    return q


def test_bistatic_wall_echo_and_direct_path_between_two_sonars(tmp_path):
    scene = two_sonars(wall_scene(tmp_path))
    sim = RigSimulator(scene)
    c = scene.environment.speed_of_sound_m_s
    array = scene.sensor.array
    emitter = LEFT + array.emitter_m  # sonar "left" fires; "right" hears (world = body)
    mics = RIGHT + array.positions_m
    pose = sim.measurements[0].pose
    heard = sim.pair(0, 1).heard(pose, None, scene.n_samples())
    kinds = np.array(heard.kinds)
    spec = np.flatnonzero(kinds == "specular")
    assert spec.size == 1
    d = np.linalg.norm(mirror(emitter) - mics, axis=1)  # the mirror-image formula
    e = heard.echoes
    assert np.max(np.abs(e.delay_s[:, spec[0]] - d / c)) < 0.01e-6
    level_db = 20 * np.log10(np.abs(e.gain[:, spec[0]]) * d)  # expected gain 1 / d
    assert np.max(np.abs(level_db)) < 0.1
    direct = np.flatnonzero(kinds == "direct")
    assert direct.size == 1
    r = np.linalg.norm(emitter - mics, axis=1)
    assert np.max(np.abs(e.delay_s[:, direct[0]] - r / c)) < 0.01e-6
    assert np.max(np.abs(20 * np.log10(np.abs(e.gain[:, direct[0]]) * r))) < 0.1


def _arrival(signal, call, fs):
    """The delay (s) of the strongest copy of `call` in `signal` (matched filter
    envelope peak, parabolic interpolation)."""
    mf = scipy.signal.correlate(signal, call, mode="full")[call.size - 1 :]
    env = np.abs(scipy.signal.hilbert(mf))
    i = int(np.argmax(env))
    a, b, c = env[i - 1], env[i], env[i + 1]
    return (i + 0.5 * (a - c) / (a - 2 * b + c)) / fs


def _crosstalk_only(scene):
    """Per recording, the crosstalk's samples: with it less without it."""
    on = RigSimulator(scene).run().recordings
    off_scene = dataclasses.replace(scene, rig=dataclasses.replace(scene.rig, crosstalk=False))
    off = RigSimulator(off_scene).run().recordings
    return on, [a.samples - b.samples for a, b in zip(on, off)]


def test_two_sonars_fired_5_ms_apart_hear_each_other(tmp_path):
    scene = two_sonars(wall_scene(tmp_path))
    c = scene.environment.speed_of_sound_m_s
    recs, cross = _crosstalk_only(scene)
    array = scene.sensor.array
    fs = scene.sensor.sample_rate_hz
    call = scene.sensor.call.sampled(fs)
    e_left, e_right = LEFT + array.emitter_m, RIGHT + array.emitter_m
    m_left, m_right = LEFT + array.positions_m[0], RIGHT + array.positions_m[0]
    # "left" (t = 0) hears "right"'s call (t = 5 ms): its direct path first
    assert [h["sensor"] for h in recs[0].metadata["crosstalk"]] == ["right"]
    expected = 0.005 + np.linalg.norm(e_right - m_left) / c
    assert _arrival(cross[0][0], call, fs) == pytest.approx(expected, abs=2e-6)
    # "right" (t = 5 ms) hears "left"'s wall echo, 5 ms less than its path
    assert [h["sensor"] for h in recs[1].metadata["crosstalk"]] == ["left"]
    expected = np.linalg.norm(mirror(e_left) - m_right) / c - 0.005
    assert _arrival(cross[1][0], call, fs) == pytest.approx(expected, abs=2e-6)
    assert set(recs[1].truth.emitter) == {"left", "right"}
    assert np.all(recs[1].truth.kind[recs[1].truth.emitter == "left"] == "specular")


def test_the_ground_truth_says_where_each_sonar_sees_the_others_calls(tmp_path):
    # "right" turned 20 degrees away from "left", fired 5 ms after it, both facing
    # the wall: each recording's truth places every path, the other's included,
    # where the hearing sonar's image shows it: along its arrival direction at the
    # hearer's array centre, at c/2 times its delay from the hearer's emission
    # (the mirror-image and straight-line formulas, in the hearer's frame, here)
    base = two_sonars(wall_scene(tmp_path))
    left, right = base.rig.sonars
    right = dataclasses.replace(right, mount=Mount(RIGHT, yaw_rad=np.deg2rad(-20.0)))
    scene = dataclasses.replace(base, rig=dataclasses.replace(base.rig, sonars=(left, right)))
    c = scene.environment.speed_of_sound_m_s
    array = scene.sensor.array
    (rec_l, rec_r) = RigSimulator(scene).run().recordings

    def frame(sonar):  # sensor -> world rotation and where its emitter and centre are
        R = sonar.mount.rotation
        centre = array.positions_m.mean(axis=0)
        return R, sonar.mount.position_m + R @ array.emitter_m, sonar.mount.position_m + R @ centre

    def expected(hearer, source, delay_s):
        R, _, centre = frame(hearer)
        u = (source - centre) / np.linalg.norm(source - centre)
        local = R.T @ u
        return delay_s, local, array.positions_m.mean(axis=0) + local * c * delay_s / 2

    R_l, e_l, c_l = frame(left)
    R_r, e_r, c_r = frame(right)
    cases = [  # (recording, emitter, kind, where the sound comes from, delay from the hearer's)
        (rec_l, "right", "direct", e_r, 0.005 + np.linalg.norm(e_r - c_l) / c),
        (rec_r, "left", "specular", mirror(e_l), np.linalg.norm(mirror(e_l) - c_r) / c - 0.005),
        (rec_r, "right", "specular", mirror(e_r), np.linalg.norm(mirror(e_r) - c_r) / c),
    ]
    for rec, emitter, kind, source, delay in cases:
        t = rec.truth
        (n,) = np.flatnonzero((t.emitter == emitter) & (t.kind == kind))
        hearer = left if rec is rec_l else right
        d, u, app = expected(hearer, source, delay)
        assert t.delay_s[n] == pytest.approx(d, abs=0.01e-6)
        np.testing.assert_allclose(t.arrival_sensor[n], u, atol=1e-7)
        np.testing.assert_allclose(t.apparent_position_sensor_m[n], app, atol=1e-5)
        pose = rec.metadata["body_pose"]
        assert pose["position_m"] == [0.0, 0.0, 0.0]  # the body at the origin: world = body
        R = R_l if rec is rec_l else R_r
        world = (c_l if rec is rec_l else c_r) - R @ array.positions_m.mean(axis=0) + R @ app
        np.testing.assert_allclose(t.apparent_position_world_m[n], world, atol=1e-5)
        if kind == "specular":  # the wall touched
            assert t.object_names[t.object_index[n]].endswith("/m")
            assert t.last_point_m[n][0] == pytest.approx(WALL_X, abs=1e-6)


def test_direct_path_off_leaves_out_a_sonars_own_leakage_not_the_others_call(tmp_path):
    # direct_path is a sonar's own emitter-to-microphone leakage; another sonar's call
    # reaching it straight is crosstalk: "left" still hears "right"'s call fired 5 ms
    # into its window at |e_right - m_left| / c after it, at 1 / distance
    base = wall_scene(tmp_path)
    quiet = dataclasses.replace(base.sensor, direct_path=False)
    scene = two_sonars(dataclasses.replace(base, sensor=quiet))
    c = scene.environment.speed_of_sound_m_s
    recs = RigSimulator(scene).run().recordings
    for rec in recs:
        own = rec.truth.emitter == rec.metadata["sensor"]
        assert "direct" not in set(rec.truth.kind[own])
    t = recs[0].truth
    (n,) = np.flatnonzero((t.emitter == "right") & (t.kind == "direct"))
    array = scene.sensor.array
    r = np.linalg.norm(RIGHT + array.emitter_m - (LEFT + array.positions_m.mean(axis=0)))
    assert t.delay_s[n] == pytest.approx(0.005 + r / c, abs=0.01e-6)
    assert 20 * np.log10(t.amplitude[n] * r) == pytest.approx(0.0, abs=0.1)


def test_a_rig_recordings_peaks_name_the_sonar_whose_call_they_carry(tmp_path):
    # "left"'s DAS image holds "right"'s call, fired 5 ms into its window
    # and heard straight, as its strongest peak: c/2 times (5 ms + the straight
    # path), towards "right"'s emitter 0.5 m to the side (azimuth -90 degrees);
    # peaks.csv's row names "right" and the direct path; the wall's echo of "left"'s
    # own call names "left"
    from acousim.imaging.run import ImagingOptions, peak_table, recording_images

    scene = two_sonars(wall_scene(tmp_path))  # noise-free: its SNR infinite
    rec = RigSimulator(scene).run().recordings[0]
    c = scene.environment.speed_of_sound_m_s
    options = ImagingOptions(methods=("das",))
    image = recording_images(rec, options)["das"]
    rows = peak_table(rec, image, threshold_db=-30, window_samples=256)
    array = scene.sensor.array
    centre = LEFT + array.positions_m.mean(axis=0)
    straight = np.linalg.norm(RIGHT + array.emitter_m - centre)
    cross = [r for r in rows if r.truth_emitter == "right" and r.truth_kind == "direct"]
    assert cross and cross[0].range_m == pytest.approx(c * (0.005 + straight / c) / 2, abs=0.02)
    assert cross[0].azimuth_deg == pytest.approx(-90.0, abs=2.0)
    own = [r for r in rows if r.truth_emitter == "left" and r.truth_kind == "specular"]
    assert own and own[0].range_m == pytest.approx(WALL_X, abs=0.02)
    assert {r.truth_emitter for r in rows if r.truth_kind} <= {"left", "right"}


def test_sonars_fired_100_ms_apart_with_a_30_ms_window_do_not_hear_each_other(tmp_path):
    base = wall_scene(tmp_path)
    c = base.environment.speed_of_sound_m_s
    call_s = base.sensor.call.duration_s
    window = 0.030
    scene = wall_scene(tmp_path, max_range_m=(window - call_s) * c / 2)
    assert scene.n_samples() / scene.sensor.sample_rate_hz == pytest.approx(window, abs=1e-5)
    scene = two_sonars(scene, times=((0.0,), (0.1,)))
    recs, cross = _crosstalk_only(scene)
    for rec, x in zip(recs, cross):
        assert rec.metadata["crosstalk"] == []
        assert not np.any(x)
        assert set(rec.truth.emitter) == {rec.metadata["sensor"]}


def test_earlier_calls_left_out_on_request(tmp_path):
    """``earlier_calls = false``: "right"'s recording (fired 5 ms after "left") leaves
    out "left"'s wall echo and is the recording without crosstalk; "left"'s keeps
    "right"'s call, emitted during its window, byte for byte."""
    scene = two_sonars(wall_scene(tmp_path))
    every = RigSimulator(scene).run().recordings
    rig = dataclasses.replace(scene.rig, earlier_calls=False)
    later_only = RigSimulator(dataclasses.replace(scene, rig=rig)).run().recordings
    quiet = dataclasses.replace(scene.rig, crosstalk=False)
    alone = RigSimulator(dataclasses.replace(scene, rig=quiet)).run().recordings
    assert [h["sensor"] for h in every[1].metadata["crosstalk"]] == ["left"]
    assert later_only[1].metadata["crosstalk"] == []
    assert later_only[1].metadata["earlier_calls"] is False
    assert "earlier_calls" not in every[1].metadata
    assert set(later_only[1].truth.emitter) == {"right"}
    assert np.array_equal(later_only[1].samples, alone[1].samples)
    assert [h["sensor"] for h in later_only[0].metadata["crosstalk"]] == ["right"]
    assert np.array_equal(later_only[0].samples, every[0].samples)
    assert not np.array_equal(later_only[0].samples, alone[0].samples)


def test_crosstalk_doppler_of_a_moving_rig_is_the_bistatic_formula(tmp_path):
    v = np.array([1.0, 0.0, 0.0])  # towards the wall
    body = Trajectory.constant(Pose(np.zeros(3)), v)
    scene = two_sonars(wall_scene(tmp_path), motion=body)
    sim = RigSimulator(scene)
    c = scene.environment.speed_of_sound_m_s
    f_c = float(np.mean(scene.sensor.call.band_hz))
    fire = sim.measurements[0]  # "left" at t = 0, heard by "right"
    heard = sim.pair(0, 1).heard(fire.pose, scene.rig.sonar_motion(0), scene.n_samples())
    kinds = np.array(heard.kinds)[heard.rows]
    spec = np.flatnonzero(kinds == "specular")
    assert spec.size == 1
    array = scene.sensor.array
    e = LEFT + array.emitter_m
    mics = RIGHT + array.positions_m
    # the sound leaves the emitter towards its image's reflection point; the
    # microphone has moved by v t on reception (t: the path over c, to first order)
    t = np.linalg.norm(mirror(e) - mics, axis=1) / c
    t = np.linalg.norm(mirror(e) - (mics + v * t[:, None]), axis=1) / c
    m = mics + v * t[:, None]
    img = mirror(e)
    hit = img + (m - img) * ((WALL_X - img[0]) / (m[:, 0] - img[0]))[:, None]  # on the wall
    u_e = (hit - e) / np.linalg.norm(hit - e, axis=1)[:, None]
    u_r = (m - hit) / np.linalg.norm(m - hit, axis=1)[:, None]
    factor = (c - u_r @ v) / (c - u_e @ v)  # moving emitter and receiver, still wall
    got = heard.rate[:, spec[0]]
    assert np.max(np.abs(got * f_c - factor * f_c)) < 5.0
    assert np.max(np.abs(factor * f_c - f_c)) > 100  # a Doppler shift that matters
    # the direct path between two sonars on one rigid body moving straight: none
    direct = np.flatnonzero(kinds == "direct")
    assert np.max(np.abs(heard.rate[:, direct[0]] - 1) * f_c) < 5.0
    # and in the recording: "right" hears "left"'s echo at the delay of its path
    recs = sim.run().recordings
    assert [h["sensor"] for h in recs[1].metadata["crosstalk"]] == ["left"]
    fs = scene.sensor.sample_rate_hz
    x = (
        recs[1].samples[0]
        - sim.pair(1, 1)
        .simulate_pose(sim.measurements[1].pose, 1, motion=scene.rig.sonar_motion(1))
        .samples[0]
    )
    expected = heard.echoes.delay_s[0, spec[0]] - 0.005
    compressed = scene.sensor.call.sampled(fs / factor[0])  # w(factor t): the chirp heard
    assert _arrival(x, compressed, fs) == pytest.approx(expected, abs=2e-6)


@pytest.mark.parametrize("processes", [2, 1])
def test_a_rigs_run_gives_the_recordings_of_one_firing_at_a_time(processes):
    """`run` makes the firings in two processes where it can fork (2), or
    prepares the next firings in threads while one renders (1): the bundled rig
    (four sonars, crosstalk heard before and during the window, in motion, the
    LiDAR) gives every firing's samples and ground truth byte for byte as
    :meth:`RigSimulator.simulate` one firing after the other."""
    scene = load_scene(REPO / "scenes" / "corridor_rig.toml")
    firings = [40, 41, 42, 43, 44]
    run = RigSimulator(scene).run(firings, processes=processes).recordings
    alone = RigSimulator(scene)
    for i, rec in zip(firings, run):
        ref = alone.simulate(i)
        assert np.array_equal(rec.samples, ref.samples)
        assert np.array_equal(rec.truth.position_world_m, ref.truth.position_world_m)
        assert list(rec.truth.emitter) == list(ref.truth.emitter)
        assert rec.metadata["crosstalk"] == ref.metadata["crosstalk"]
        assert np.array_equal(rec.lidar.points_m, ref.lidar.points_m)
    assert {len(r.metadata["crosstalk"]) for r in run} == {2}  # heard before and during


def test_a_scene_without_a_rig_is_a_rig_of_one(tmp_path):
    scene = wall_scene(tmp_path)
    a = Simulator(scene).run()
    b = RigSimulator(scene).run().recordings
    assert len(a) == len(b) == 1
    assert a[0].samples.tobytes() == b[0].samples.tobytes()


def test_a_rig_in_the_scene_file(tmp_path):
    wall_scene(tmp_path)  # writes wall.obj
    scene = parse_scene(
        {
            "body": {"pose": {"position_m": [0, 0, 0], "velocity_m_s": [0.5, 0, 0]}},
            "rig": {
                "firing": "round_robin",
                "rate_hz": 10,
                "crosstalk": False,
                "earlier_calls": False,
            },
            "sensors": [
                {"name": "a", "array": "urtis_v1", "mount": {"position_m": [0.1, 0.2, 0]}},
                {
                    "name": "b",
                    "array": "urtis_v1",
                    "mount": {"position_m": [0.1, -0.2, 0], "rotation_deg": [0, 0, -30]},
                    "firing": {"rate_hz": 20, "offset_s": 0.01, "count": 2},
                },
            ],
            "lidars": [{"preset": "vlp16", "position_m": [0, 0, 0.4]}],
            "materials": [{"name": "m", "reflection": 1.0}],
            "meshes": [{"file": "wall.obj", "material": "m"}],
        },
        base_dir=tmp_path,
    )
    rig = scene.rig
    assert [s.name for s in rig.sonars] == ["a", "b"] and not rig.crosstalk
    assert not rig.earlier_calls
    assert rig.sonars[0].firing == Firing(10.0, 0.0)  # round robin: 1 / (2 x 10 Hz) apart
    ms = rig.measurements()
    assert [(m.sonar, round(m.time_s, 9)) for m in ms] == [(0, 0.0), (1, 0.01), (1, 0.06)]
    b = ms[2].pose  # the body moved 3 cm; the mount turned the sonar 30° right
    np.testing.assert_allclose(b.position_m, [0.1 + 0.5 * 0.06, -0.2, 0], atol=1e-12)
    np.testing.assert_allclose(np.rad2deg(b.yaw_rad), -30, atol=1e-9)
    assert rig.lidars[0].position_m == (0.0, 0.0, 0.4)
    assert scene.sensor.poses[0].position_m.tolist() == [0.1, 0.2, 0.0]
    # sonar b's recording carries the LiDAR's scan, its mounting in b's frame
    run = RigSimulator(scene).run([1])
    rec = run.recordings[0]
    mount_b = np.eye(4)
    turn = np.deg2rad(-30)
    mount_b[:2, :2] = [[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]]
    mount_b[:3, 3] = [0.1, -0.2, 0]
    body_from_lidar = mount_b @ rec.lidar.to_sensor
    np.testing.assert_allclose(body_from_lidar[:3, 3], [0, 0, 0.4], atol=1e-12)
    np.testing.assert_allclose(body_from_lidar[:3, :3], np.eye(3), atol=1e-12)
    assert len(rec.lidar) > 0 and [s.name for s in run.scans] == ["VLP-16"]


@pytest.mark.parametrize(
    "change, key",
    [
        ({"sensor": {}}, "sensors"),
        ({"sensors": [{"pose": {}}]}, "sensors[0].pose"),
        ({"sensors": [{"mount": {"position": [0, 0, 0]}}]}, "sensors[0].mount"),
        ({"sensors": [{"firing": {"times_s": [0.1, 0.0]}}]}, "sensors[0].firing"),
        ({"sensors": [{"name": "x"}, {"name": "x"}]}, "sensors"),
    ],
)
def test_bad_rig_tables_name_their_key(tmp_path, change, key):
    from acousim.scene import SceneError

    data = {"sensors": [{}], "points": [{"position_m": [1, 0, 0]}], **change}
    with pytest.raises(SceneError) as err:
        parse_scene(data, base_dir=tmp_path)
    assert err.value.key.startswith(key)


def test_rig_recordings_keep_their_sonar_and_emitters_in_files(tmp_path):
    import processing as P

    scene = two_sonars(wall_scene(tmp_path))
    recs = RigSimulator(scene).run().recordings
    P.save_recordings(tmp_path / "r.h5", list(recs))
    back = P.load_recordings(tmp_path / "r.h5")
    for a, b in zip(recs, back):
        assert b.metadata["sensor"] == a.metadata["sensor"]
        assert b.metadata["mount"] == a.metadata["mount"]
        np.testing.assert_array_equal(b.truth.emitter, a.truth.emitter)
    assert back[1].metadata["crosstalk"][0]["sensor"] == "left"


def test_simulate_and_image_a_rig_scene_file_by_sensor(tmp_path, capsys):
    import processing as P
    from acousim.cli import main

    (tmp_path / "r.toml").write_text(
        """
[rig]
rate_hz = 20
[[sensors]]
name = "a"
array = "paper_8x8"
call = "paper"
sample_rate_hz = 500000
mount = { position_m = [0, 0.1, 0] }
[[sensors]]
name = "b"
array = "paper_8x8"
call = "paper"
sample_rate_hz = 500000
mount = { position_m = [0, -0.1, 0], rotation_deg = [0, 0, -10] }
[simulation]
max_range_m = 1.5
absorption = false
[[points]]
position_m = [1.0, 0.0, 0.0]
"""
    )
    out = tmp_path / "r.h5"
    assert main(["simulate", str(tmp_path / "r.toml"), "--out", str(out)]) == 0
    recs = P.load_recordings(out)
    assert [r.metadata["sensor"] for r in recs] == ["a", "b"]  # round robin, 25 ms apart
    assert recs[1].metadata["mount"]["rotation_deg"] == pytest.approx([0, 0, -10])
    pics = tmp_path / "pics"
    args = ["image", str(out), "--method", "das", "--out", str(pics), "--no-3d"]
    assert main([*args, "--sensor", "b"]) == 0
    assert main([*args, "--sensor", "c"]) != 0
    assert "sonar 'c'" in capsys.readouterr().err
    assert main(["info", str(out)]) == 0
    assert "sonar 'b' fired at 0.025 s" in capsys.readouterr().out


def test_chirp_export_of_a_rig_whole_or_one_sonar(tmp_path, capsys):
    import h5py

    import processing as P
    from acousim.cli import main

    scene = two_sonars(wall_scene(tmp_path))
    P.save_recordings(tmp_path / "r.h5", list(RigSimulator(scene).run().recordings))
    out = tmp_path / "c.h5"
    args = ["export", str(tmp_path / "r.h5"), "--format", "chirp", "--out", str(out)]
    assert main(args) == 0  # the whole rig: an acoustic sensor per sonar
    with h5py.File(out) as f:
        names = [f[f"sensors/acoustic_sensor_{n:02d}"].attrs["name"] for n in (0, 1)]
        assert names == ["left", "right"]
    assert [r.metadata["sensor"] for r in P.load_recordings(out)] == ["left", "right"]
    out.unlink()
    assert main([*args, "--sensor", "right"]) == 0
    (back,) = P.load_recordings(out)
    assert back.metadata["sensor"] == "right"
    np.testing.assert_array_equal(back.truth.emitter, ["right", "right", "left"])


def test_chirp_export_of_one_sonar_keeps_its_mount(tmp_path, capsys):
    """`export --sensor right --format chirp`: the sonar's acoustic sensor is named
    "right", base_link is the body (its pose in the odometry) and the sonar's mount
    (turned 20 degrees, 0.25 m to the right; the recording's metadata 'mount') is
    inv(base_link_to_origin), as the whole rig's file places each sonar; chirppy,
    where installed, reads the same transform."""
    import h5py

    import processing as P
    from acousim.cli import main

    base = two_sonars(wall_scene(tmp_path))
    left, right = base.rig.sonars
    body = Pose(np.array([0.4, -0.3, 0.45]), yaw_rad=np.deg2rad(30.0))
    right = dataclasses.replace(right, mount=Mount(RIGHT, yaw_rad=np.deg2rad(-20.0)))
    rig = dataclasses.replace(base.rig, sonars=(left, right), poses=(body,))
    recs = list(RigSimulator(dataclasses.replace(base, rig=rig)).run().recordings)
    P.save_recordings(tmp_path / "r.h5", recs)
    out = tmp_path / "c.h5"
    args = ["export", str(tmp_path / "r.h5"), "--sensor", "right", "--format", "chirp"]
    assert main([*args, "--out", str(out)]) == 0
    mount = recs[1].metadata["mount"]
    assert mount == {"position_m": [0.0, -0.25, 0.0], "rotation_deg": [0.0, 0.0, -20.0]}

    def turned(yaw_deg: float, at) -> np.ndarray:  # 4x4 of a turn about z and a shift
        c, s = np.cos(np.deg2rad(yaw_deg)), np.sin(np.deg2rad(yaw_deg))
        T = np.eye(4)
        T[:2, :2], T[:3, 3] = [[c, -s], [s, c]], at
        return T

    want_mount = turned(-20.0, [0.0, -0.25, 0.0])
    with h5py.File(out) as f:
        assert list(f["sensors"]) == [
            "acoustic_sensor_00", "acoustic_transmitter_00", "odometry_00"
        ]  # fmt: skip
        assert f["sensors/acoustic_sensor_00"].attrs["name"] == "right"
        np.testing.assert_allclose(
            f["sensors/acoustic_sensor_00/calibration/to_origin"], np.eye(4), atol=1e-15
        )
        to_origin = f["transforms/base_link_to_origin"][()]
        np.testing.assert_allclose(np.linalg.inv(to_origin), want_mount, atol=1e-12)
        odo = f["sensors/odometry_00/data"]
        np.testing.assert_allclose(odo["position"][0], [0.4, -0.3, 0.45], atol=1e-12)
        np.testing.assert_allclose(odo["yaw"][0], np.deg2rad(30.0), atol=1e-12)
    (back,) = P.load_recordings(out)
    assert back.metadata["sensor"] == "right" and back.metadata["mount"] == mount
    np.testing.assert_allclose(back.provenance.pose.yaw_rad, np.deg2rad(10.0), atol=1e-12)
    try:
        import chirppy
    except ImportError:
        return
    with chirppy.CHIRPDataset(out) as ds:
        T = ds.get_transform("acoustic_sensor_00", "base_link")
        np.testing.assert_allclose(T, want_mount, atol=1e-12)
        np.testing.assert_allclose(
            ds.get_odometry(0).get_pose_matrix(0), turned(30.0, [0.4, -0.3, 0.45]), atol=1e-12
        )


def test_a_single_sensor_simulator_refuses_a_rig(tmp_path):
    from processing.base.errors import InputError

    with pytest.raises(InputError, match="RigSimulator"):
        Simulator(two_sonars(wall_scene(tmp_path)))


def test_schedules_round_robin_and_simultaneous():
    from acousim.scene.rig import schedule

    rr = schedule(4, 10.0, "round_robin")
    assert [f.offset_s for f in rr] == pytest.approx([0.0, 0.025, 0.05, 0.075])
    assert all(f.rate_hz == 10.0 for f in rr)
    assert [f.offset_s for f in schedule(3, 20.0, "simultaneous")] == [0.0, 0.0, 0.0]
    # over a 1 s trajectory: 11 firings from the start, 10 from an offset of 25 ms
    assert len(rr[0].times(0.0, 1.0)) == 11 and len(rr[1].times(0.0, 1.0)) == 10
    np.testing.assert_allclose(rr[1].times(2.0, 1.0)[:2], [2.025, 2.125])


def test_a_mount_rides_a_turning_body():
    """A sonar mounted 0.3 m ahead of a body turning at 90 deg/s while it drives:
    its position is the body's plus the turned lever arm, its velocity that
    position's derivative (central differences here)."""
    from acousim.scene.rig import MountedTrajectory

    body = Trajectory.constant(Pose(np.zeros(3)), (0.5, 0, 0), (0, 0, np.pi / 2))
    mount = Mount.degrees([0.3, 0.1, 0.2], [0, 0, 30])
    m = MountedTrajectory.of(body, mount)
    t, h = 0.4, 1e-6
    turn = np.pi / 2 * t
    arm = np.array(
        [0.3 * np.cos(turn) - 0.1 * np.sin(turn), 0.3 * np.sin(turn) + 0.1 * np.cos(turn), 0.2]
    )
    np.testing.assert_allclose(m.position(t), [0.5 * t, 0, 0] + arm, atol=1e-12)
    numeric = (m.position(t + h) - m.position(t - h)) / (2 * h)
    np.testing.assert_allclose(m.velocity(t), numeric, atol=1e-8)
    yaw = np.arctan2(m.rotation(t)[1, 0], m.rotation(t)[0, 0])
    assert yaw == pytest.approx(turn + np.deg2rad(30))
    p = mount.place(body.pose(t))
    np.testing.assert_allclose(p.position_m, m.position(t), atol=1e-12)
    # a point 0.2 m along the sonar's axis, at two times at once
    c, s = np.cos(turn + np.deg2rad(30)), np.sin(turn + np.deg2rad(30))
    ahead = m.to_world(np.array([[0.2, 0, 0]]), np.array([t, t]))
    expected = [0.5 * t, 0, 0] + arm + [0.2 * c, 0.2 * s, 0]
    np.testing.assert_allclose(ahead[1, 0], expected, atol=1e-12)


def test_a_call_traced_only_as_far_as_it_is_heard_gives_the_same_crosstalk(tmp_path):
    scene = two_sonars(wall_scene(tmp_path))
    sim = RigSimulator(scene)
    first, later = sim.measurements  # "right" fires 5 ms into "left"'s window
    n = scene.n_samples()
    window = n / scene.sensor.sample_rate_hz
    reach = sim._reach(later, window - 0.005)
    assert reach is not None and reach < 2 * scene.simulation.max_range_m
    cut, cut_truth = sim._crosstalk(later, first, n)
    sim._reach = lambda f, w: None  # every path the scene traces
    full, full_truth = sim._crosstalk(later, first, n)
    np.testing.assert_array_equal(cut, full)
    np.testing.assert_array_equal(cut_truth.kind, full_truth.kind)


def test_a_call_heard_after_its_shorter_paths_ends_gives_the_same_crosstalk(tmp_path):
    scene = two_sonars(wall_scene(tmp_path))
    sim = RigSimulator(scene)
    first, later = sim.measurements  # "right" (5 ms) hears "left"'s wall echo
    call_s = scene.sensor.call.duration_s
    short = sim._short_of(first, 0.005 - call_s)
    c = scene.environment.speed_of_sound_m_s
    direct = np.linalg.norm(LEFT - RIGHT)  # gone before "right" records: left out
    assert direct < short < c * (0.005 - call_s) < 2 * (WALL_X - 0.1)
    n = scene.n_samples()
    cut, cut_truth = sim._crosstalk(first, later, n)
    sim._short_of = lambda f, gone_s: None  # every path to the kinematics
    full, full_truth = sim._crosstalk(first, later, n)
    np.testing.assert_array_equal(cut, full)
    np.testing.assert_array_equal(cut_truth.kind, full_truth.kind)
    assert list(full_truth.kind) == ["specular"]


def test_crosstalk_rendered_with_the_hearing_sonars_echoes_in_motion(tmp_path):
    # in motion a sonar's crosstalk is rendered in one pass with its own echoes:
    # "right" (fired 5 ms after "left", both riding a body at 1 m/s towards the
    # wall) hears "left"'s wall echo at the mirror image's delay and 1 / path level
    v = np.array([1.0, 0.0, 0.0])
    body = Trajectory.constant(Pose(np.zeros(3)), v)
    scene = two_sonars(wall_scene(tmp_path), motion=body)
    c = scene.environment.speed_of_sound_m_s
    fs = scene.sensor.sample_rate_hz
    array = scene.sensor.array
    recs, cross = _crosstalk_only(scene)
    assert [h["sensor"] for h in recs[1].metadata["crosstalk"]] == ["left"]
    image = mirror(LEFT + array.emitter_m)  # of the emitter when the call starts (t = 0)
    for m in (0, 7, 29):
        mic = RIGHT + array.positions_m[m]  # at t = 0; at t: + v t
        t = 0.0
        for _ in range(50):  # c t = |mic + v t - image|: the start of the call arrives
            t = np.linalg.norm(mic + v * t - image) / c
        # heard time-compressed by the bistatic Doppler factor of the receiver and
        # the emitter's image (its velocity mirrored in the wall)
        u = (mic + v * t - image) / np.linalg.norm(mic + v * t - image)
        factor = (c - u @ v) / (c - u @ (v * np.array([-1.0, 1.0, 1.0])))
        heard = scene.sensor.call.sampled(fs / factor)  # w(factor s)
        x = cross[1][m]  # the echo alone (the direct path ended before the window)
        assert _arrival(x, heard, fs) == pytest.approx(t - 0.005, abs=0.1e-6)
        level = np.sqrt(np.sum(x**2) / np.sum(heard**2))  # its energy over the call's
        assert 20 * np.log10(level * c * t) == pytest.approx(0.0, abs=0.1)


@pytest.mark.parametrize("n", [2, 6])
def test_a_firing_traces_its_own_call_and_the_calls_it_hears_whatever_the_sonars(
    tmp_path, monkeypatch, n
):
    """A rig of N sonars costs N sensors' measurements: its world is made once, and a
    firing traces its own call and each call that reaches its window, nothing more,
    whatever N.  N sonars facing the wall fire round robin 5 ms apart (24 firings);
    firing 12's window (under 20 ms: 3 m of range and the call) is reached by the
    calls fired within its longest path and call before it (17.5 ms and the call:
    three) and within its window after it (three)."""
    made, traced = [], []
    init, trace = Tracer.__init__, Tracer.traced
    monkeypatch.setattr(Tracer, "__init__", lambda s, *a, **k: made.append(1) or init(s, *a, **k))
    monkeypatch.setattr(Tracer, "traced", lambda s, *a, **k: traced.append(1) or trace(s, *a, **k))
    scene = wall_scene(tmp_path)
    step = 0.005
    sonars = tuple(
        RigSonar(
            f"s{k}",
            scene.sensor,
            Mount(np.array([0.0, 0.1 * k, 0.0])),
            Firing(rate_hz=1 / (n * step), offset_s=k * step, count=24 // n),
        )
        for k in range(n)
    )
    sim = RigSimulator(dataclasses.replace(scene, rig=Rig(sonars=sonars)))
    fs = scene.sensor.sample_rate_hz
    window = scene.n_samples() / fs
    longest = 2 * scene.simulation.max_range_m / scene.environment.speed_of_sound_m_s
    m = sim.measurements[12]
    times = np.array([f.time_s for f in sim.measurements])
    call = scene.sensor.call.duration_s
    reach = (times > m.time_s - longest - call) & (times < m.time_s + window)
    reach[12] = False
    assert reach.sum() == 6
    sim.simulate(12)
    assert len(made) == 1  # one world for the rig
    assert len(traced) == 1 + reach.sum()  # its own call, and each call reaching it
