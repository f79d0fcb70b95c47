"""Motion within a measurement: Doppler and retarded time against closed forms.

The expected numbers are computed here from the physics (a monostatic sensor closing
on a wall at v: echo frequency f (c + v) / (c - v), start of the echo 2 d / (c + v)),
or are the values of issue 14 (matched-filter loss and peak shift of the sweeps
with the RTIS calls' 10 % taper; an analytic computation at 4 MHz gives 1.85 dB and
9.64 us: untapered, the linear chirp would lose 3.1 dB), or come from a second
computation written in the test.
"""

import numpy as np
import pytest
from scipy.signal import correlate, hilbert

import acousim
import processing as P
from acousim.core.echoes import Echoes
from acousim.kinematics import SensorKinematics, arrivals
from acousim.kinematics.reference import render_doppler_reference
from acousim.scene import Pose, load_scene, parse_scene
from acousim.scene.trajectory import Trajectory
from acousim.simulator import Simulator
from acousim.synth.doppler import render_doppler
from acousim.synth.options import Capture, Noise, RenderOptions
from acousim.synth.signal_model import simulate
from acousim.trace.motion.following import MovingPaths
from tests import REPO
from tests.oracles.doppler import turning_past_four_points

SCENES = REPO / "scenes"
C = 343.0
FS = 450e3
ONE = P.Array("one", np.zeros((1, 3)))  # a microphone on the emitter: monostatic


def wall_paths(d):
    """The wall x = d as the image source of the emitter at the origin (built here)."""
    n = np.array([1.0, 0.0, 0.0])
    return MovingPaths(
        np.array([[2 * d, 0.0, 0.0]]),
        np.zeros(1),
        np.ones(1),
        n[None],
        np.ones(1, int),
        (np.eye(3) - 2 * np.outer(n, n))[None],
        np.zeros(1, int),
        np.zeros((1, 3)),
        np.full(1, 2 * d),
    )


def one_echo(delay, rate, wf, n):
    e = Echoes(np.array([[delay]]), np.ones((1, 1)), np.array([[C * delay]]), np.ones(1, int))
    return render_doppler(e, np.array([[rate]]), wf, FS, n)[0]


@pytest.mark.slow
def test_wall_approached_at_1_m_s_doppler_and_delay():
    d, v = 2.0, 1.0
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [v, 0, 0])
    wf = P.Waveform("linear", 40e3, 40e3, 5e-3)  # a 5 ms tone burst
    n = int(0.03 * FS)
    kin = SensorKinematics(traj, pose, ONE, n / FS, 2.5e-4)
    arr = arrivals(wall_paths(d), kin, wf.duration_s, C, np.array([1.0, 0, 0]))
    assert abs(arr.echoes.delay_s[0, 0] - 2 * d / (C + v)) < 0.1e-6
    assert arr.rate[0, 0] == pytest.approx((C + v) / (C - v), rel=1e-9)
    y = render_doppler(arr.echoes, arr.rate, wf, FS, n)[0]
    spec = np.abs(np.fft.rfft(y, 2**23))
    f = np.fft.rfftfreq(2**23, 1 / FS)
    assert abs(f[np.argmax(spec)] - 40e3 * (C + v) / (C - v)) < 5.0
    assert abs(40e3 * (C + v) / (C - v) - 40233) < 1  # the number


def _mf_peak(y, template):
    env = np.abs(hilbert(correlate(y, template, mode="full")))
    k = int(np.argmax(env))
    # parabolic interpolation of the envelope peak
    a, b, c = env[k - 1 : k + 2]
    off = 0.5 * (a - c) / (a - 2 * b + c)
    return b - 0.25 * (a - c) * off, (k + off - (template.size - 1)) / FS


def _still_and_closing(wf, v=2.0, d=2.0):
    """Matched-filter (peak, time) of the echo of a reflector at `d` m, still and
    closing at `v` m/s (compressed by (c + v) / (c - v))."""
    template = wf.sampled(FS)
    n = int(0.02 * FS)
    t0 = 2 * d / (C + v)
    still = _mf_peak(one_echo(t0, 1.0, wf, n), template)
    return still, _mf_peak(one_echo(t0, (C + v) / (C - v), wf, n), template)


def test_linear_chirp_at_2_m_s_loses_1_85_db_of_matched_filter_peak():
    wf = P.linear_chirp(80e3, 20e3, 2.5e-3, taper=0.1)  # the RTIS calls' taper
    (still, _), (moving, _) = _still_and_closing(wf)
    loss = 20 * np.log10(still / moving)
    assert loss == pytest.approx(1.85, abs=0.2)


def test_hyperbolic_sweep_at_2_m_s_moves_its_peak_by_9_7_us():
    wf = P.hyperbolic_sweep(80e3, 20e3, 2.5e-3, taper=0.1)  # the RTIS calls' taper
    (p_still, t_still), (p_moving, t_moving) = _still_and_closing(wf)
    assert abs(t_moving - t_still) * 1e6 == pytest.approx(9.7, abs=0.5)
    assert 20 * np.log10(p_still / p_moving) < 0.1  # Doppler tolerant: a small loss


def test_moving_reflector_equals_the_mirrored_moving_sensor():
    """Monostatic and collinear: a reflector closing at v and a sensor closing at v
    give the same echo (both start at 2 r / (c + v), both compressed by
    (c + v) / (c - v)); and both match those closed forms."""
    r, v = 3.0, 1.5
    wf = P.rtis_call("default_20_80")
    n = int(0.025 * FS)
    pose = Pose([0.0, 0, 0])
    axis = np.array([1.0, 0, 0])
    sensor = SensorKinematics(Trajectory.constant(pose, [v, 0, 0]), pose, ONE, n / FS, 2.5e-4)
    fixed = MovingPaths.points([[r, 0, 0]], [1.0], [[0, 0, 0]], np.zeros(3))
    a = arrivals(fixed, sensor, wf.duration_s, C, axis)
    still = SensorKinematics(None, pose, ONE, n / FS, None)
    moving = MovingPaths.points([[r, 0, 0]], [1.0], [[-v, 0, 0]], np.zeros(3))
    b = arrivals(moving, still, wf.duration_s, C, axis)
    for x in (a, b):
        assert x.echoes.delay_s[0, 0] == pytest.approx(2 * r / (C + v), abs=1e-12)
        assert x.rate[0, 0] == pytest.approx((C + v) / (C - v), rel=1e-12)
    ya = render_doppler(a.echoes, a.rate, wf, FS, n)[0]
    yb = render_doppler(b.echoes, b.rate, wf, FS, n)[0]
    # the spreading differs between the frames by v^2 / c^2 (r_e r_m: r^2 (c - v) /
    # (c + v) for the moving sensor, r^2 c^2 / (c + v)^2 for the moving reflector);
    # the waveforms are the same
    ratio = C**2 / (C**2 - v**2)
    assert np.max(np.abs(ya)) / np.max(np.abs(yb)) == pytest.approx(ratio, rel=1e-9)
    assert np.max(np.abs(ya / ratio - yb)) <= 1e-9 * np.max(np.abs(yb))


@pytest.mark.slow
def test_fast_renderer_against_the_per_sample_reference():
    """A sensor driving at 1 m/s and turning at 90 deg/s, three reflectors (one of
    them moving): the linear-delay renderer within -60 dB of the exact one."""
    arr = P.preset("urtis_v1")
    arr = P.Array("two", arr.positions_m[[0, 17]], np.array([0.0, 0, -0.012]))
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [1.0, 0.2, 0], [0, 0, np.deg2rad(90)])
    wf = P.rtis_call("default_20_80")
    pts = np.array([[2.0, 0.3, 0.1], [1.5, -1.0, 0.0], [2.5, 1.0, 0.2]])
    vel = np.array([[0, 0, 0], [0, 0, 0], [-0.5, 0, 0]])
    paths = MovingPaths.points(pts, np.ones(3), vel, pose.to_world(arr.emitter_m))
    n = int(0.022 * FS)
    kin = SensorKinematics(traj, pose, arr, n / FS, 2.5e-4)
    a = arrivals(paths, kin, wf.duration_s, C, np.array([1.0, 0, 0]))
    fast = render_doppler(a.echoes, a.rate, wf, FS, n)
    exact = render_doppler_reference(
        paths, SensorKinematics.exact(traj, pose, arr), wf, FS, n, C, a.echoes.gain
    )
    err = 20 * np.log10(np.linalg.norm(fast - exact) / np.linalg.norm(exact))
    assert err <= -60


def test_fast_renderer_keeps_the_direct_path_without_a_response():
    """No Doppler, no path response: the direct path (order 0) and an echo as the
    static renderer gives them (the direct path was once dropped here)."""
    from acousim.synth.render import render

    wf = P.rtis_call("default_20_80")
    delay = np.array([[1.0e-4, 3.0e-3], [1.1e-4, 3.2e-3]])
    echoes = Echoes(
        delay, np.array([[1.0, 0.1], [1.0, 0.1]]), delay * C, np.array([0, 1]), np.zeros(2)
    )
    fast = render_doppler(echoes, np.ones((2, 2)), wf, FS, 4000)
    static = render(echoes, wf, FS, 4000, interpolator="sinc")
    assert np.linalg.norm(fast - static) <= 1e-6 * np.linalg.norm(static)


def test_static_reference_agrees_with_static_echoes():
    """No motion: the reference renders the plain delayed call (a second check of
    the retarded-time solver against |A - e| + |A - m|)."""
    arr = P.Array("two", np.array([[0.0, 0.05, 0], [0, -0.05, 0.02]]))
    pose = Pose([0.0, 0, 0])
    pts = np.array([[1.0, 0.4, 0.0]])
    paths = MovingPaths.points(pts, [1.0], [[0, 0, 0]], np.zeros(3))
    wf = P.rtis_call("default_20_80")
    n = int(0.012 * FS)
    kin = SensorKinematics(None, pose, arr, n / FS, None)
    a = arrivals(paths, kin, wf.duration_s, C, np.array([1.0, 0, 0]))
    d = (np.linalg.norm(pts[0]) + np.linalg.norm(pts[0] - arr.positions_m, axis=1)) / C
    assert np.allclose(a.echoes.delay_s[:, 0], d, atol=1e-15, rtol=0)
    assert np.allclose(a.rate, 1.0, atol=1e-12, rtol=0)


def _turning_scene(rate_deg_s):
    return parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "call": "default_20_80",
                "direct_path": False,
                "pose": {"position_m": [0.0, 0, 0], "angular_rate_deg_s": [0, 0, rate_deg_s]},
            },
            "simulation": {"max_range_m": 4.5, "absorption": False},
            "points": [{"position_m": [4.0 * np.cos(0.2), 4.0 * np.sin(0.2), 0.0]}],
        }
    )


def test_turning_sensor_sees_a_point_moved_by_the_angle_swept():
    step = 0.5
    grid = P.Grid.degrees(azimuth=(-10.0, 30.0), elevation=(0.0, 0.0), step=step)
    settings = P.ProcessingSettings(grid=grid, range_limits_m=(3.5, 4.5))
    peak = {}
    for rate in (0.0, 90.0):
        sc = _turning_scene(rate)
        assert (sc.sensor.motion is None) == (rate == 0)
        rec = Simulator(sc).simulate_pose(sc.sensor.poses[0])
        img = P.acoustic_image(rec, "das", settings)
        r, e, k = np.unravel_index(np.argmax(img.power), img.power.shape)
        peak[rate] = np.rad2deg(img.azimuth_rad[k])
    # received while the array has turned by the rate times the time of flight
    # (to the middle of the call)
    swept = 90.0 * (8.0 / C + 1.25e-3)
    assert abs((peak[0.0] - peak[90.0]) - swept) <= step


def test_static_scene_takes_the_unchanged_path():
    """No motion: the simulator's samples are bit-identical to tracing and rendering
    the same pose by hand through the static renderer."""
    sc = load_scene(SCENES / "points.toml")
    assert sc.sensor.motion is None
    sim = Simulator(sc)
    pose = sc.sensor.poses[0]
    rec = sim.simulate_pose(pose, 0)
    paths = sim.paths(pose)
    mics = pose.to_world(sc.sensor.array.positions_m)
    echoes = paths.echoes(mics, pose.rotation[:, 0], sim.c)
    seed = int(np.random.SeedSequence([sc.simulation.seed, 0]).generate_state(1)[0])
    ref = simulate(
        echoes,
        Capture(sc.sensor.array, sc.sensor.call, sc.sensor.sample_rate_hz, sc.n_samples(), sim.c),
        noise=Noise(snr_db=sc.simulation.snr_db, seed=seed, reference="echoes"),
        options=RenderOptions(interpolator=sc.simulation.fractional_delay),
        response=sim.response,
    )
    assert rec.samples.tobytes() == ref.samples.tobytes()
    assert "motion" not in rec.metadata


def test_trajectory_passes_through_its_poses_and_turns_left():
    poses = [
        Pose([0.1 * i, 0.02 * i**2, 0.3], np.deg2rad(5.0 * i), time_s=0.1 * i) for i in range(5)
    ]
    tr = Trajectory.through(poses)
    for p in poses:
        assert np.allclose(tr.position(p.time_s), p.position_m, atol=1e-12)
        assert np.allclose(tr.rotation(p.time_s), p.rotation, atol=1e-12)
    # halfway between poses 1 and 2 the yaw is halfway (slerp about z)
    assert tr.pose(0.15).yaw_rad == pytest.approx(np.deg2rad(7.5), abs=1e-12)
    assert tr.angular_velocity(0.15) == pytest.approx([0, 0, np.deg2rad(50.0)], abs=1e-9)
    const = Trajectory.constant(Pose([0.0, 0, 0], 0.3), [1.0, 0, 0], [0, 0, 1.0])
    assert const.pose(0.2).yaw_rad == pytest.approx(0.5, abs=1e-12)
    assert np.allclose(const.position(0.2), [0.2, 0, 0])


def test_scene_motion_keys():
    sc = load_scene(SCENES / "corridor.toml")
    assert isinstance(sc.sensor.motion, Trajectory)  # a drive moves by default
    data = {
        "sensor": {
            "array": "urtis_v1",
            "trajectory": {"poses": [[0, 0, 0.3, 0], [0.1, 0, 0.3, 10]], "continuous": False},
        },
        "points": [{"position_m": [1.0, 0, 0], "velocity_m_s": [-1.0, 0, 0]}],
    }
    sc = parse_scene(data)
    assert sc.sensor.motion is None and sc.points[0].moving
    data["sensor"] = {"array": "urtis_v1", "pose": {"velocity_m_s": [0.5, 0, 0]}}
    sc = parse_scene(data)
    assert np.allclose(sc.sensor.motion.velocity(0.0), [0.5, 0, 0])
    data["sensor"]["pose"]["velocity_m_s"] = [0.5, 0]
    with pytest.raises(ValueError, match=r"sensor.pose.velocity_m_s"):
        parse_scene(data)


def test_moving_scene_records_its_motion():
    sc = parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "pose": {"velocity_m_s": [1.0, 0, 0], "angular_rate_deg_s": [0, 0, 30]},
            },
            "simulation": {"max_range_m": 3.0},
            "points": [
                {"position_m": [2.0, 0, 0]},
                {"position_m": [2.0, 1, 0], "velocity_m_s": [0, -1, 0]},
            ],
        }
    )
    rec = Simulator(sc).simulate_pose(sc.sensor.poses[0])
    m = rec.metadata["motion"]
    assert m["velocity_m_s"] == pytest.approx([1.0, 0, 0])
    assert m["angular_velocity_deg_s"] == pytest.approx([0, 0, 30])
    assert m["doppler_max"] == pytest.approx((C + 1.0) / (C - 1.0), rel=2e-3)
    assert rec.truth.velocity_world_m_s[-1].tolist() == [0, -1, 0]
    assert np.all(np.isfinite(rec.samples)) and np.any(rec.samples)


def test_first_order_image_sources_follow_the_emitter_exactly():
    """Geometry during the measurement: the image sources predicted from the emission
    pose (mirrored with the emitter) against those traced again at the pose of the
    end of the call (the shoebox, sensor at 2 m/s and 90 deg/s)."""
    sc = load_scene(SCENES / "shoebox.toml")
    sim = Simulator(sc)
    pose = sc.sensor.poses[0]
    traj = Trajectory.constant(pose, [2.0, 0.5, 0], [0, 0, np.deg2rad(90)])
    later = traj.pose(pose.time_s + sc.sensor.call.duration_s)
    array = sc.sensor.array
    e0, e1 = pose.to_world(array.emitter_m), later.to_world(array.emitter_m)
    first = sim.paths(pose)
    mp = MovingPaths.from_traced(first, e0)
    one = (first.kind == 1) & (first.order == 1)
    assert one.sum() >= 4
    anchors, firsts = mp.moved(e0, e1)
    traced = sim.paths(later)
    img = traced.anchor_m[(traced.kind == 1) & (traced.order == 1)]
    dist = np.linalg.norm(anchors[one][:, None] - img[None], axis=2).min(axis=1)
    assert np.all(dist < 1e-9)
    # second order: the image sources too (their planes recovered from the path)
    # (paths at an edge, both reflections at one point, keep Fermat's law: their
    # planes cannot be recovered from the path)
    two = (first.kind == 1) & (first.order == 2) & np.any(mp.mirror != 0, axis=(1, 2))
    img2 = traced.anchor_m[(traced.kind == 1) & (traced.order == 2)]
    mic = later.to_world(array.positions_m[0])
    pred = firsts[two] + np.linalg.norm(anchors[two] - mic, axis=1)
    true = np.linalg.norm(img2 - mic, axis=1)
    err = np.abs(pred[:, None] - true[None]).min(axis=1)
    assert two.sum() >= 3 and np.all(err < 1e-9)


def test_dataset_spec_randomises_speed_and_turn_rate(tmp_path):
    from acousim.dataset import load_spec
    from acousim.dataset.generation import _motion, _pose, sample_parameters

    p = tmp_path / "drive.toml"
    p.write_text(
        f"""
[dataset]
name = "drive"
samples = 2
shard_size = 2
seed = 1

[[scenes]]
file = "{SCENES}/wall.toml"

[randomize]
speed_m_s = {{ dist = "uniform", range = [0.5, 1.5] }}
turn_rate_deg_s = {{ dist = "uniform", range = [-90.0, 90.0] }}
"""
    )
    spec = load_spec(p)
    params = sample_parameters(spec, 0)
    c = params["conditions"]
    assert 0.5 <= c["speed_m_s"] <= 1.5 and -90 <= c["turn_rate_deg_s"] <= 90
    pose = _pose(params["pose"])
    tr = _motion(pose, c)
    assert np.linalg.norm(tr.velocity(0.0)) == pytest.approx(c["speed_m_s"])
    assert np.rad2deg(tr.angular_velocity(0.0)[2]) == pytest.approx(c["turn_rate_deg_s"])


def test_standing_still_in_motion_renders_as_the_static_scene():
    """The moving pipeline (kinematics, Doppler nodes, compressed sets, absorption and
    directivity factorised) with zero velocity against the static renderer: the
    shoebox with and without its direct path (40 dB above the echoes), within -70 dB
    of the echoes."""
    import dataclasses

    base = load_scene(SCENES / "shoebox.toml")
    for direct in (False, True):
        sensor = dataclasses.replace(base.sensor, direct_path=direct)
        sc = dataclasses.replace(base, sensor=sensor)
        sim = Simulator(sc)
        pose = sc.sensor.poses[0]
        still = sim.simulate_pose(pose, 0, motion=None).samples
        moving = sim.simulate_pose(pose, 0, motion=Trajectory.constant(pose)).samples
        if not direct:
            echoes = still
        err = 20 * np.log10(np.linalg.norm(moving - still) / np.linalg.norm(echoes))
        assert err < -70


def test_point_on_its_own_track():
    """A reflector walking along a track: where and how fast it is at the start of
    the emission comes from the track (straight here: 1 m/s along -y)."""
    sc = parse_scene(
        {
            "sensor": {"array": "urtis_v1", "direct_path": False},
            "simulation": {"max_range_m": 3.0, "absorption": False},
            "points": [
                {"track": [[0.0, 2.0, 1.0, 0.0], [1.0, 2.0, 0.0, 0.0], [2.0, 2.0, -1.0, 0]]}
            ],
        }
    )
    p = sc.points[0]
    assert p.moving
    pos, vel = p.at(0.5)
    assert np.allclose(pos, [2.0, 0.5, 0.0]) and np.allclose(vel, [0.0, -1.0, 0.0])
    with pytest.raises(ValueError, match=r"points\[0\].track"):
        parse_scene({"sensor": {"array": "urtis_v1"}, "points": [{"track": [[0, 1, 2]]}]})
    pose = Pose([0.0, 0, 0], time_s=1.0)  # the point crosses the axis at x = 2 m
    sim = Simulator(sc)
    rec = sim.simulate_pose(pose)
    assert rec.truth.velocity_world_m_s[0] == pytest.approx([0, -1.0, 0])
    truth = rec.truth.position_world_m[0]
    assert truth == pytest.approx([2.0, 0.0, 0.0])  # where it is at the emission
    assert np.any(rec.samples)


def test_motion_settings_are_checked_in_files_and_in_code(tmp_path):
    """One declaration per motion setting: the scene file and the constructors refuse
    the same values (InputError naming the key and the value), and a recording of a
    moving scene keeps its truth velocities through its HDF5 file."""
    from processing import load_recordings, save_recordings
    from processing.base.errors import InputError

    base = {"sensor": {"array": "urtis_v1"}, "points": [{"position_m": [1.0, 0, 0]}]}
    for table, key, value in [
        ("points", "velocity_m_s", [500.0, 0, 0]),
        ("points", "velocity_m_s", [1.0, 0]),
        ("sensor.pose", "velocity_m_s", [0, float("nan"), 0]),
        ("sensor.pose", "angular_rate_deg_s", [0, 0, 1e5]),
        ("sensor.trajectory", "continuous", "yes"),
        ("points", "track", [[0.0, 1, 0, 0], [0.0, 2, 0, 0]]),
    ]:
        data = {"sensor": {"array": "urtis_v1"}, "points": [{"position_m": [1.0, 0, 0]}]}
        if table == "points":
            data["points"][0][key] = value
            where = f"points[0].{key}"
        elif table == "sensor.pose":
            data["sensor"]["pose"] = {key: value}
            where = f"sensor.pose.{key}"
        else:
            data["sensor"]["trajectory"] = {"poses": [[0, 0, 0, 0], [0.1, 0, 0, 0]], key: value}
            where = f"sensor.trajectory.{key}"
        with pytest.raises(InputError) as err:
            parse_scene(data)
        assert err.value.key == where, (where, str(err.value))
    with pytest.raises(InputError, match="PointItem.velocity_m_s"):
        acousim.PointItem((1.0, 0, 0), velocity_m_s=(500.0, 0, 0))
    with pytest.raises(InputError, match="PointItem.position_m"):
        acousim.PointItem()
    with pytest.raises(InputError, match="PointItem.track"):
        acousim.PointItem(track=[[0.0, 1, 0, 0], [0.0, 2, 0, 0]])
    with pytest.raises(InputError, match="angular_velocity_rad_s"):
        Trajectory.constant(Pose([0.0, 0, 0]), (0, 0, 0), (0, 0, 100.0))
    with pytest.raises(InputError, match="Sensor.motion"):
        acousim.Sensor(motion="fast")
    point = acousim.PointItem(track=[[0.0, 2, 1, 0], [1.0, 2, -1, 0]])
    assert point.position_m == (2.0, 1.0, 0.0) and point.moving
    sc = parse_scene({**base, "points": [{"position_m": [2.0, 0, 0], "velocity_m_s": [-1, 0, 0]}]})
    rec = Simulator(sc).simulate_pose(sc.sensor.poses[0])
    save_recordings(tmp_path / "r.h5", [rec])
    (back,) = load_recordings(tmp_path / "r.h5")
    np.testing.assert_array_equal(back.truth.velocity_world_m_s, rec.truth.velocity_world_m_s)
    assert back.truth.velocity_world_m_s[-1].tolist() == [-1.0, 0, 0]  # the point
    assert back.metadata["motion"]["velocity_m_s"] == [0, 0, 0]
    still = Simulator(parse_scene(base)).simulate_pose(Pose([0.0, 0, 0]))
    save_recordings(tmp_path / "s.h5", [still])
    (back,) = load_recordings(tmp_path / "s.h5")
    assert back.truth.velocity_world_m_s is None


def test_doppler_series_is_the_interpolant_through_the_nodes():
    """The Doppler terms (Chebyshev series of the templates' coefficients) give, at any
    factor in the interval, the polynomial through the K node values: against a
    polynomial fitted here through the nodes (numpy, power basis)."""
    from acousim.synth.compress import chebyshev_terms
    from acousim.synth.doppler import _chebyshev_argument, _chebyshev_coefficients, doppler_nodes

    wf = P.rtis_call("default_20_80")
    nodes = doppler_nodes(0.9985, 1.0058, wf, FS)
    assert nodes.size > 4
    rng = np.random.default_rng(7)
    values = rng.standard_normal((nodes.size, 3))  # three "templates" sampled at the nodes
    rate = rng.uniform(nodes.min(), nodes.max(), (4, 5))
    gain = rng.uniform(0.5, 2.0, (4, 5))
    terms = chebyshev_terms(_chebyshev_argument(nodes, rate), gain, nodes.size)  # (K, 4, 5)
    got = np.einsum("kmn,kc->mnc", terms, _chebyshev_coefficients(values))
    x = (nodes - nodes.mean()) * 100
    for c in range(3):
        poly = np.polynomial.Polynomial.fit(x, values[:, c], nodes.size - 1)
        want = gain * poly((rate - nodes.mean()) * 100)
        assert np.max(np.abs(got[..., c] - want)) < 1e-8 * np.abs(values).max()


@pytest.mark.slow
def test_fast_renderer_with_absorption_and_directivity_against_exact_filtering():
    """Doppler, air absorption and emitter directivity together (the sets compressed
    across Doppler terms and response terms) against the exact echo of each path
    filtered by its own response (per path, by FFT, here): within -60 dB."""
    case = turning_past_four_points(FS, C)
    fast = render_doppler(case.echoes, case.rate, case.wf, FS, case.n, response=case.response)
    exact = case.exact
    err = 20 * np.log10(np.linalg.norm(fast - exact) / np.linalg.norm(exact))
    assert err <= -60


@pytest.mark.slow
def test_moving_recording_does_not_depend_on_the_hosts_blas_threads():
    """The same seed gives the same bytes whatever the host's BLAS threads: with two
    BLAS threads the moving corridor's gain-set products summed in another order (a
    different last bit) before BLAS was pinned to one thread; the entry point pins
    it (acousim.process.configure), in a process started with 1 or 2 threads."""
    import hashlib
    import os
    import subprocess
    import sys

    script = (
        "import hashlib\n"
        "from acousim.process import configure\n"
        "from acousim.scene import load_scene\n"
        "from acousim.simulator import Simulator\n"
        "configure()\n"
        f"sim = Simulator(load_scene({str(SCENES / 'corridor.toml')!r}))\n"
        "rec = sim.simulate_pose(sim.scene.sensor.poses[5], 5)\n"
        "print(hashlib.sha256(rec.samples.tobytes()).hexdigest())\n"
    )
    out = []
    for threads in ("1", "2"):
        env = {**os.environ, "OPENBLAS_NUM_THREADS": threads, "OMP_NUM_THREADS": threads}
        run = subprocess.run(
            [sys.executable, "-c", script], capture_output=True, text=True, env=env, check=True
        )
        out.append(run.stdout.strip())
    # and in this process (configured by the tests' conftest, as the command line)
    sim = Simulator(load_scene(SCENES / "corridor.toml"))
    here = sim.simulate_pose(sim.scene.sensor.poses[5], 5).samples
    assert out[0] == out[1] == hashlib.sha256(here.tobytes()).hexdigest()
