"""Moving meshes (a wall, a box, a sphere that move during the measurement) against
closed forms and a second computation written here.

Closed forms (monostatic, head-on, exact for a moving sensor and for a moving
reflector alike): an echo from a plane or a sphere's nearest point that is d away at
the start of the emission and closing at v starts at 2 d / (c + v) and is time
compressed by (c + v) / (c - v) (a 40 kHz tone comes back at 40,233 Hz at 1 m/s).
"""

import dataclasses

import numpy as np
import pytest
import trimesh

import acousim
import processing as P
from acousim.kinematics import SensorKinematics, arrivals
from acousim.scene import Pose, parse_scene
from acousim.scene.trajectory import Trajectory
from acousim.simulator import Simulator
from acousim.trace.tracer import Tracer

FS = 450e3
ONE = P.Array("one", np.zeros((1, 3)))  # a microphone on the emitter: monostatic
AXIS = np.array([1.0, 0, 0])
TONE = P.Waveform("linear", 40e3, 40e3, 5e-3)  # a 5 ms tone burst
C = acousim.Environment().speed_of_sound_m_s


def _scene(meshes, poses=None, motion=None, array=ONE, call=TONE, rays=2000):
    sensor = acousim.Sensor(
        array=array,
        call=call,
        direct_path=False,
        poses=tuple(poses or [Pose([0.0, 0, 0])]),
        motion=motion,
    )
    sim = acousim.Simulation(max_range_m=4.0, rays=rays, absorption=False)
    return acousim.Scene(meshes=meshes, sensor=sensor, simulation=sim)


def _wall(x_front, velocity=(0.0, 0.0, 0.0)):
    """A 20 m x 20 m wall whose front face (normal -x) is at x = x_front."""
    return acousim.MeshItem(
        trimesh.creation.box((0.2, 20, 20)),
        acousim.Material("wall", reflection=1.0),
        position_m=(x_front + 0.1, 0, 0),
        velocity_m_s=velocity,
    )


def _arrivals(sim, pose):
    """Reception times of the first sample (M, N) and Doppler factors (M, N) of every
    path, and the kinds and true positions and velocities of the paths."""
    moving, pos, kinds, vel = sim.moving_paths(pose)
    sensor = sim.scene.sensor
    n = sim.scene.n_samples()
    kin = SensorKinematics(sensor.motion, pose, sensor.array, n / FS, 2.5e-4)
    a = arrivals(moving, kin, sensor.call.duration_s, sim.c, pose.rotation[:, 0])
    return a.echoes.delay_s, a.rate, np.array(kinds), pos, vel


def _peak_hz(y):
    spec = np.abs(np.fft.rfft(y, 2**23))
    return np.fft.rfftfreq(2**23, 1 / FS)[np.argmax(spec)]


def test_wall_approaching_equals_sensor_approaching_the_wall():
    d, v = 2.0, 1.0
    pose = Pose([0.0, 0, 0])
    wall_moves = _scene([_wall(d, (-v, 0, 0))])
    sensor_moves = _scene([_wall(d)], motion=Trajectory.constant(pose, [v, 0, 0]))
    f_expected = 40e3 * (C + v) / (C - v)
    assert abs(f_expected - 40233) < 1  # the number
    for sc in (wall_moves, sensor_moves):
        sim = Simulator(sc)
        delay, rate, kinds, _, _ = _arrivals(sim, pose)
        assert kinds.tolist() == ["specular"]
        assert abs(delay[0, 0] - 2 * d / (C + v)) < 0.1e-6
        assert rate[0, 0] == pytest.approx((C + v) / (C - v), rel=1e-9)
        rec = sim.simulate_pose(pose)
        assert abs(_peak_hz(rec.samples[0]) - f_expected) < 5.0


def test_receding_wall_and_a_sphere_closing():
    """A wall moving away at 2 m/s (echo late, stretched) and a sphere closing at 1 m/s
    (its glint: a point reached straight from the emitter)."""
    d, v = 2.5, 2.0
    sim = Simulator(_scene([_wall(d, (v, 0, 0))]))
    delay, rate, _, _, _ = _arrivals(sim, Pose([0.0, 0, 0]))
    assert abs(delay[0, 0] - 2 * d / (C - v)) < 0.1e-6
    assert rate[0, 0] == pytest.approx((C - v) / (C + v), rel=1e-9)
    a, d, v = 0.1, 1.5, 1.0
    ball = acousim.MeshItem(
        trimesh.creation.icosphere(5, radius=a), position_m=(d + a, 0, 0), velocity_m_s=(-v, 0, 0)
    )
    sim = Simulator(_scene([ball]))
    delay, rate, kinds, pos, vel = _arrivals(sim, Pose([0.0, 0, 0]))
    glint = np.argmin(delay[0])
    # the tessellated sphere's nearest point lies within 0.1 mm of the true sphere
    assert abs(delay[0, glint] - 2 * np.linalg.norm(pos[glint]) / (C + v)) < 0.1e-6
    assert np.linalg.norm(pos[glint]) == pytest.approx(d, abs=1e-4)
    assert rate[0, glint] == pytest.approx((C + v) / (C - v), rel=1e-6)
    assert vel[glint] == pytest.approx([-v, 0, 0])


def test_passing_box_follows_its_track():
    """A box (front face 0.25 m before its centre) walking along a track towards the
    sensor at 1 m/s: at each pose the echo of its front face starts at
    2 x_front(t) / (c + 1) (t: the pose's time on the track's clock)."""
    rows = [[0.0, 4.0, 0.0, 0.0], [1.0, 3.0, 0.0, 0.0], [2.0, 2.0, 0.0, 0.0]]
    box = acousim.MeshItem(trimesh.creation.box((0.5, 0.6, 1.8)), track=rows)
    times = [0.0, 0.4, 1.1, 1.9]
    poses = [Pose([0.0, 0, 0], time_s=t) for t in times]
    sim = Simulator(_scene([box], poses=poses))
    for pose in poses:
        x_front = 4.0 - pose.time_s - 0.25
        delay, rate, kinds, pos, vel = _arrivals(sim, pose)
        k = np.flatnonzero(kinds == "specular")
        assert k.size == 1
        assert pos[k[0]] == pytest.approx([x_front, 0, 0], abs=1e-9)
        assert vel[k[0]] == pytest.approx([-1.0, 0, 0], abs=1e-9)
        assert abs(delay[0, k[0]] - 2 * x_front / (C + 1.0)) < 0.1e-6


def reference_reception(scene, velocity, pose, mic, tau, trajectory=None, c=C):
    """Reception time at microphone `mic` (an index) of the sample emitted at `tau`
    (after the start of the emission at `pose`) by the first-order reflection on the
    scene's one mesh, which translates at `velocity` (3,): the mesh placed where it is
    at the reflection instant t_x and traced again there from where the emitter is at
    `tau` (a static scene each time, the sensor on `trajectory` or still), t_x and the
    reception time t iterated until the sound takes t_x - tau to the reflection point
    and t - t_x from there to where the microphone is at t."""
    array = scene.sensor.array

    def at(t):
        return pose if trajectory is None else trajectory.pose(pose.time_s + t)

    emit = at(tau)
    e = emit.to_world(array.emitter_m)
    item = scene.meshes[0]
    t_x = t = tau
    for _ in range(50):
        T = np.array(item.transform, float)
        T[:3, 3] += np.asarray(velocity, float) * (pose.time_s + t_x)
        moved = dataclasses.replace(item, transform=T, velocity_m_s=(0.0, 0.0, 0.0))
        traced = Tracer(dataclasses.replace(scene, meshes=(moved,))).trace(emit)
        (A,) = traced.anchor_m[(traced.kind == 1) & (traced.order == 1)]
        n = (e - A) / np.linalg.norm(e - A)
        mic_t = at(t).to_world(array.positions_m[mic])
        # where the line from the image to the microphone crosses the plane
        s = np.dot((e + A) / 2 - A, n) / np.dot(mic_t - A, n)
        x = A + s * (mic_t - A)
        new_x, new_t = tau + np.linalg.norm(x - e) / c, tau + np.linalg.norm(mic_t - A) / c
        done = max(abs(new_x - t_x), abs(new_t - t)) < 1e-14
        t_x, t = new_x, new_t
        if done:
            break
    return t


@pytest.mark.parametrize("sensor_moves", [False, True])
def test_oblique_wall_against_tracing_at_the_reflection_instant(sensor_moves):
    """A wall turned 20 degrees, moving at 1.66 m/s (closing at 1.09 m/s), seen
    by the uRTIS array (microphones off the emitter), still or driving at 2 m/s and
    turning at 180 deg/s: the reception times of the first and last sample of the
    call at two microphones against the reference."""
    arr = P.preset("urtis_v1")
    yaw = np.deg2rad(20)
    n = np.array([-np.cos(yaw), -np.sin(yaw), 0.0])  # towards the sensor
    T = np.eye(4)
    T[:3, :3] = trimesh.transformations.rotation_matrix(yaw, [0, 0, 1])[:3, :3]
    T[:3, 3] = -2.0 * n - 0.1 * n
    velocity = 1.5 * n + np.array([0.8, -1.0, 0.3])  # closing and sliding
    wall = acousim.MeshItem(
        trimesh.creation.box((0.2, 20, 20)), acousim.Material("w", 1.0), T, velocity_m_s=velocity
    )
    call = P.rtis_call("default_20_80")
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [2.0, 0.4, 0], [0, 0, np.pi]) if sensor_moves else None
    sc = _scene([wall], array=arr, call=call, motion=traj)
    sim = Simulator(sc)
    moving, _, kinds, vel = sim.moving_paths(pose)
    assert kinds.count("specular") == 1 and vel[0] == pytest.approx(velocity)
    kin = SensorKinematics(traj, pose, arr, sc.n_samples() / FS, None)
    a = arrivals(moving, kin, call.duration_s, C, AXIS)
    # the model's reception times of the first and last sample of the call
    t0 = a.echoes.delay_s[:, 0] - a.curvature_s[:, 0] * (2 / 3)
    t1 = t0 + call.duration_s / a.rate[:, 0]
    for m in (0, arr.n_mics - 1):
        r0 = reference_reception(sc, velocity, pose, m, 0.0, traj)
        r1 = reference_reception(sc, velocity, pose, m, call.duration_s, traj)
        assert abs(t0[m] - r0) < 1e-9 and abs(t1[m] - r1) < 1e-9
        # the wall's motion matters at this tolerance: frozen, 37 us off
        frozen = reference_reception(sc, (0, 0, 0), pose, m, 0.0, traj)
        assert abs(frozen - r0) > 10e-6


def test_moving_box_occludes_at_the_emission_instant():
    """A box crossing between the sensor and a wall: the wall's echo is hidden while
    the box stands in front of it at the start of the emission, and back after."""
    box = acousim.MeshItem(
        trimesh.creation.box((0.3, 0.6, 1.0)), position_m=(1.5, -1.0, 0), velocity_m_s=(0, 1.0, 0)
    )
    poses = [Pose([0.0, 0, 0], time_s=t) for t in (1.0, 2.5)]  # box at y = 0, then 1.5
    sim = Simulator(_scene([_wall(3.0), box], poses=poses))
    assert not isinstance(sim.tracer, Tracer)  # the world rebuilt per instant
    _, _, kinds0, pos0, vel0 = _arrivals(sim, poses[0])
    _, _, kinds1, pos1, vel1 = _arrivals(sim, poses[1])
    spec0, spec1 = pos0[kinds0 == "specular"], pos1[kinds1 == "specular"]
    on_wall = lambda p: np.abs(p[:, 0] - 3.0) < 1e-9  # noqa: E731
    on_box = lambda p: np.abs(p[:, 0] - 1.35) < 1e-9  # noqa: E731
    assert on_box(spec0).sum() == 1 and not on_wall(spec0[np.abs(spec0[:, 1]) < 0.2]).any()
    assert on_wall(spec1).sum() == 1 and not on_box(spec1).any()
    # the ground truth: the box's echo moves at the box's velocity, the wall's not
    assert vel0[kinds0 == "specular"][on_box(spec0)][0] == pytest.approx([0, 1.0, 0])
    assert np.all(vel1[kinds1 == "specular"][on_wall(spec1)] == 0)


def test_recording_stores_emission_pose_and_velocities():
    d, v = 2.0, 1.0
    sc = _scene([_wall(d, (-v, 0, 0))], poses=(Pose([0.0, 0, 0], time_s=0.5),))
    rec = Simulator(sc).simulate_pose(sc.sensor.poses[0])
    assert rec.metadata["motion"]["emission_pose"]["time_s"] == 0.5
    assert rec.metadata["motion"]["doppler_max"] == pytest.approx((C + v) / (C - v), rel=1e-9)
    # where the wall is at the emission (it started at 2 m and moved 0.5 s at 1 m/s)
    assert rec.truth.position_world_m[0] == pytest.approx([d - 0.5 * v, 0, 0])
    assert rec.truth.velocity_world_m_s[0] == pytest.approx([-v, 0, 0])


def test_mesh_motion_keys_in_files_and_code(tmp_path):
    trimesh.creation.box((0.5, 0.5, 0.5)).export(tmp_path / "box.stl")
    base = {"sensor": {"array": "urtis_v1"}, "simulation": {"rays": 500}}
    sc = parse_scene(
        {
            **base,
            "meshes": [{"file": "box.stl", "position_m": [2, 0, 0], "velocity_m_s": [0, 1, 0]}],
        },
        base_dir=tmp_path,
    )
    m = sc.meshes[0]
    assert m.moving and np.allclose(m.at(2.0)[0], [2, 2, 0])
    sc = parse_scene(
        {**base, "meshes": [{"file": "box.stl", "track": [[0, 2, 0, 0], [1, 2, 1, 0]]}]},
        base_dir=tmp_path,
    )
    assert np.allclose(sc.meshes[0].at(0.5)[0], [2, 0.5, 0])
    with pytest.raises(ValueError, match=r"meshes\[0\].velocity_m_s"):
        parse_scene(
            {**base, "meshes": [{"file": "box.stl", "velocity_m_s": [500, 0, 0]}]},
            base_dir=tmp_path,
        )
    with pytest.raises(ValueError, match=r"meshes\[0\].track"):
        parse_scene(
            {**base, "meshes": [{"file": "box.stl", "track": [[1, 2, 0, 0], [0, 2, 1, 0]]}]},
            base_dir=tmp_path,
        )
    with pytest.raises(ValueError, match=r"MeshItem.velocity_m_s"):
        acousim.MeshItem(trimesh.creation.box(), velocity_m_s=(0, 0))
    # a static scene keeps its one world
    still = parse_scene(
        {**base, "meshes": [{"file": "box.stl", "position_m": [2, 0, 0]}]}, base_dir=tmp_path
    )
    assert isinstance(Simulator(still).tracer, Tracer)


def _mirror(p, n, off):
    return p - 2 * (np.dot(n, p) - off) * n


def _cross(a, b, n, off):
    """Where the segment a -> b meets the plane n . x = off."""
    return a + (off - np.dot(n, a)) / np.dot(n, b - a) * (b - a)


def _two_bounce(planes, tau):
    """Reception time (monostatic, at the origin) of the sample emitted at `tau` by
    way of two planes in order, each ``(n, offset(t))`` (n . x = offset at time t):
    image sources of the planes where they are at each reflection instant, the
    instants iterated until the sound takes them to travel between the points."""
    (n1, off1), (n2, off2) = planes
    e = m = np.zeros(3)
    t1 = t2 = tau
    for _ in range(100):
        A1 = _mirror(e, n1, off1(t1))
        A2 = _mirror(A1, n2, off2(t2))
        x2 = _cross(A2, m, n2, off2(t2))
        x1 = _cross(A1, x2, n1, off1(t1))
        new1 = tau + np.linalg.norm(x1 - e) / C
        new2 = new1 + np.linalg.norm(x2 - x1) / C
        if max(abs(new1 - t1), abs(new2 - t2)) < 1e-15:
            break
        t1, t2 = new1, new2
    return tau + np.linalg.norm(m - A2) / C


def test_wall_and_floor_both_orders_follow_the_wall():
    """A wall closing at 1.5 m/s above a still floor tilted by 10 degrees: the two
    second-order echoes (floor then wall, wall then floor: the moving wall last or
    first) against the retarded-time solution of the two planes."""
    d, v, h, tilt = 2.0, 1.5, 0.4, np.deg2rad(10)
    R = trimesh.transformations.rotation_matrix(tilt, [0, 1, 0])
    T = R.copy()
    T[:3, 3] = (0, 0, -h - 0.1)
    floor = acousim.MeshItem(trimesh.creation.box((20, 20, 0.2)), acousim.Material("f", 1.0), T)
    n_floor = R[:3, :3] @ [0, 0, 1.0]
    off_floor = np.dot(n_floor, T[:3, :3] @ [0, 0, 0.1] + T[:3, 3])
    wall = (np.array([1.0, 0, 0]), lambda t: d - v * t)
    still = (n_floor, lambda t: off_floor)
    sc = _scene([_wall(d, (-v, 0, 0)), floor])
    sim = Simulator(sc)
    moving, pos, kinds, _ = sim.moving_paths(Pose([0.0, 0, 0]))
    kin = SensorKinematics(None, Pose([0.0, 0, 0]), ONE, sc.n_samples() / FS, 2.5e-4)
    a = arrivals(moving, kin, TONE.duration_s, C, AXIS)
    t0 = a.echoes.delay_s[0] - a.curvature_s[0] * (2 / 3)
    t1 = t0 + TONE.duration_s / a.rate[0]
    two = np.flatnonzero((np.array(kinds) == "specular") & (moving.order == 2))
    last_on_wall = np.abs(pos[two, 0] - d) < 1e-9
    assert two.size == 2 and last_on_wall.sum() == 1
    for k, wall_last in zip(two, last_on_wall):
        planes = (still, wall) if wall_last else (wall, still)
        assert abs(t0[k] - _two_bounce(planes, 0.0)) < 1e-9
        assert abs(t1[k] - _two_bounce(planes, TONE.duration_s)) < 1e-9
        frozen = (still, (wall[0], lambda t: d)) if wall_last else ((wall[0], lambda t: d), still)
        assert abs(_two_bounce(frozen, 0.0) - t0[k]) > 1e-6  # the motion matters


@pytest.mark.slow
def test_fast_renderer_against_the_reference_with_moving_meshes():
    """A closing wall and a sphere crossing, the sensor driving and turning: the fast
    renderer within -60 dB of the exact per-sample one (same paths)."""
    from acousim.kinematics.reference import render_doppler_reference
    from acousim.synth.doppler import render_doppler

    arr = P.preset("urtis_v1")
    two = P.Array("2 mics", arr.positions_m[[0, 29]], np.array([0.0, 0, -0.012]))
    ball = acousim.MeshItem(
        trimesh.creation.icosphere(4, radius=0.1), position_m=(1.5, 0.4, 0), velocity_m_s=(0, -1, 0)
    )
    call = P.rtis_call("default_20_80")
    pose = Pose([0.0, 0, 0])
    traj = Trajectory.constant(pose, [1.0, 0.2, 0], [0, 0, np.deg2rad(90)])
    sc = _scene([_wall(2.5, (-1.0, 0, 0)), ball], array=two, call=call, motion=traj)
    sim = Simulator(sc)
    moving, _, _, _ = sim.moving_paths(pose)
    n = int(0.02 * FS)
    kin = SensorKinematics(traj, pose, two, n / FS, 2.5e-4)
    a = arrivals(moving, kin, call.duration_s, C, AXIS)
    assert a.rate.max() > 1.005  # Doppler from the motion
    fast = render_doppler(a.echoes, a.rate, call, FS, n)
    ref = render_doppler_reference(
        moving, SensorKinematics.exact(traj, pose, two), call, FS, n, C, a.echoes.gain
    )
    err = 20 * np.log10(np.linalg.norm(fast - ref) / np.linalg.norm(ref))
    assert len(moving) == 2 and err < -60


def test_moving_wall_with_a_table_material_follows_its_table():
    """A wall closing at 1 m/s whose reflection is 1 below 35 kHz and 0.5 above 45 kHz
    (a table): tone bursts at 25 and 70 kHz come back, at their spectral peak, at the
    table's level relative to the same wall of reflection 1 (0 dB and -6.02 dB; the
    Doppler shift of 0.6 % moves neither tone off its flat part of the table; the
    peak of the waveform would not do: the burst's on and off clicks are broadband
    and reach the flat part below 35 kHz)."""
    table = acousim.Material(
        "panel", reflection=(1.0, 1.0, 0.5, 0.5), frequencies_khz=(20.0, 35.0, 45.0, 90.0)
    )
    for f_hz, expect_db in ((25e3, 0.0), (70e3, 20 * np.log10(0.5))):
        tone = P.Waveform("linear", f_hz, f_hz, 2e-3)
        levels = []
        for material in (table, acousim.Material("hard", reflection=1.0)):
            wall = dataclasses.replace(_wall(2.0, (-1.0, 0, 0)), material=material)
            rec = Simulator(_scene([wall], call=tone)).run()[0]
            levels.append(np.abs(np.fft.rfft(rec.samples[0], 2**20)).max())
        assert 20 * np.log10(levels[0] / levels[1]) == pytest.approx(expect_db, abs=0.1)
