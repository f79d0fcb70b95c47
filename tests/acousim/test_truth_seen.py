"""The ground truth of what the sensor sees (delay, arrival direction, apparent
position, chain, object) against references that are not ours: pyroomacoustics'
image sources in a shoebox, and closed-form geometry in a two-wall hallway."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import trimesh

import processing as P
from acousim.scene import load_scene, parse_scene
from acousim.simulator import Simulator
from tests import REPO

SCENES = REPO / "scenes"
ROOM = np.array([[-1.0, 3.2], [-1.6, 1.9], [-1.1, 1.5]])  # scenes/build_scenes.py


def _shoebox(order: int):
    scene = load_scene(SCENES / "shoebox.toml")
    sim = dataclasses.replace(
        scene.simulation, beam_deg=180.0, bounces=order, max_range_m=12.0, energy_floor_db=-120.0
    )
    return dataclasses.replace(scene, simulation=sim)


def test_apparent_positions_are_pyroomacoustics_image_sources_halfway():
    """Every specular path of order 1-3 of a shoebox: its delay at the array centre
    is |image - centre| / c and its apparent position lies halfway to the image
    source along the arrival direction, with the image sources of pyroomacoustics
    (within 1 mm and 0.01 us)."""
    pra = pytest.importorskip("pyroomacoustics")
    scene = _shoebox(3)
    pose = scene.sensor.poses[0]
    rec = Simulator(scene).simulate_pose(pose)
    t, c = rec.truth, scene.environment.speed_of_sound_m_s
    assert t.has_apparent
    emitter = pose.to_world(scene.sensor.array.emitter_m)
    centre = pose.to_world(scene.sensor.array.positions_m).mean(axis=0)
    origin = ROOM[:, 0]
    room = pra.ShoeBox(ROOM[:, 1] - origin, fs=450000, max_order=3, ray_tracing=False)
    room.add_source(emitter - origin)
    room.add_microphone_array((centre - origin)[:, None])
    room.image_source_model()
    src = room.sources[0]
    keep = (src.orders >= 1) & (src.orders <= 3)
    images, orders = src.images[:, keep].T + origin, src.orders[keep]
    assert len(images) == 6 + 18 + 38  # first, second, third order of a box
    spec = np.flatnonzero(t.kind == "specular")
    found = set()
    for img, order in zip(images, orders):
        d = np.linalg.norm(img - centre)
        u = (img - centre) / d
        want = centre + u * d / 2
        err = np.linalg.norm(t.apparent_position_world_m[spec] - want, axis=1)
        j = spec[np.argmin(err)]
        assert err.min() <= 1e-3, f"image {img} (order {order}): nearest {err.min():.4f} m"
        assert t.order[j] == order
        assert abs(t.delay_s[j] - d / c) <= 0.01e-6
        np.testing.assert_allclose(t.arrival_sensor[j], u @ pose.rotation, atol=1e-6)
        # the sensor frame is the world frame through the pose
        np.testing.assert_allclose(
            pose.to_world(t.apparent_position_sensor_m[j][None])[0], want, atol=1e-6
        )
        found.add(int(j))
    assert len(found) == len(images), "two image sources matched one path"


def test_first_order_apparent_position_is_the_reflection_point():
    """A first-order echo from an emitter at the array centre shows where it
    reflected (the reflection point; the chain's first point is its last)."""
    scene = _shoebox(1)
    array = dataclasses.replace(
        scene.sensor.array, emitter_m=scene.sensor.array.positions_m.mean(axis=0)
    )
    scene = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, array=array))
    t = Simulator(scene).simulate_pose(scene.sensor.poses[0]).truth
    one = np.flatnonzero(t.order == 1)
    assert one.size == 6
    np.testing.assert_allclose(t.apparent_position_world_m[one], t.position_world_m[one], atol=1e-9)
    np.testing.assert_allclose(t.first_point_m[one], t.last_point_m[one], atol=0)
    # every face of the box is the one object, the wall
    assert t.object_names == ("shoebox/wall",)
    assert np.all(t.object_index[t.kind != "direct"] == 0)


def _hallway(tmp: Path, yaw_deg: float = 90.0):
    """Two parallel walls 2 m apart (y = -1 and y = +1, 30 m long, 3 m high), the
    sensor in the middle at the origin facing across (+y by default)."""
    for y, name in ((1.0, "left"), (-1.0, "right")):
        q = np.array([[-15, y, -1.5], [15, y, -1.5], [15, y, 1.5], [-15, y, 1.5]], float)
        tris = np.array([q[[0, 1, 2]], q[[0, 2, 3]]])
        trimesh.Trimesh(tris.reshape(-1, 3), np.arange(6).reshape(-1, 3)).export(
            tmp / f"{name}.obj"
        )
    return parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "direct_path": False,
                "pose": {"position_m": [0, 0, 0], "yaw_deg": yaw_deg},
            },
            "simulation": {"max_range_m": 3.0, "bounces": 2, "snr_db": 60.0},
            "materials": [{"name": "plaster", "reflection": 0.9}],
            "meshes": [
                {"file": "left.obj", "material": "plaster"},
                {"file": "right.obj", "material": "plaster"},
            ],
        },
        base_dir=tmp,
    )


def test_hallway_across_and_back_is_matched_to_the_far_wall(tmp_path):
    """Facing a wall 1 m away across a 2 m hallway: the echo that crosses the
    hallway and comes back (1 + 2 + 1 m) is imaged at 2 m straight ahead, where no
    surface is; its peak is matched to a specular path of order 2 whose last
    reflection is on the far wall (behind the sensor), within one resolution cell."""
    from acousim.imaging.matching import image_resolution, match_peaks
    from acousim.imaging.run import peak_table

    scene = _hallway(tmp_path)
    rec = Simulator(scene).simulate_pose(scene.sensor.poses[0])
    grid = P.Grid.degrees((-60, 60), (-30, 30), 2.0)
    settings = P.ProcessingSettings(grid=grid, energy_fraction=0.0, range_limits_m=(0.5, 2.8))
    image = P.acoustic_images(rec, ("das",), settings)["das"]
    peaks = image.peaks(-40.0)
    # the independent reference: the image source of the two walls, halfway
    far = (abs(peaks.range_m - 2.0) < 0.1) & (np.abs(peaks.azimuth_rad) < np.deg2rad(10))
    assert far.any(), "no peak at 2 m ahead"
    res = image_resolution(rec, image, settings.window)
    m = match_peaks(rec, peaks, res)
    k = np.flatnonzero(far)[0]
    assert m.index[k] >= 0 and m.kind[k] == "specular" and m.order[k] == 2
    j = m.index[k]
    t = rec.truth
    # its last reflection is on the far wall (y = -1 in the world: behind the sensor)
    assert t.last_point_m[j][1] == pytest.approx(-1.0, abs=1e-6)
    assert t.first_point_m[j][1] == pytest.approx(1.0, abs=1e-6)
    assert t.object_name()[j] == "right/plaster"
    # within one resolution cell of the peak, and its last reflection is not
    assert abs(m.range_offset_m[k]) <= res.range_m / 2 and m.offset_rad[k] <= res.angle_rad
    assert np.linalg.norm(t.position_sensor_m[j]) == pytest.approx(1.0, abs=0.05)
    row = peak_table(rec, image, threshold_db=-40.0, index=0)[k]  # peaks.csv's row
    assert (row.truth_kind, row.truth_order, row.truth_object) == ("specular", 2, "right/plaster")


def test_pole_peak_is_one_echo_and_an_edge_peak_beyond_its_cell_is_unmatched(tmp_path):
    """Looking straight down at a floor on a grid to +-90 degrees elevation: one peak
    at the pole (not one per azimuth), matched to the floor's first-order echo.  A
    peak on the grid's edge whose echo lies outside the grid is left unmatched and
    says so."""
    from acousim.imaging.matching import (
        EDGE_NOT_IN_CELL,
        image_resolution,
        match_peaks,
        on_grid_edge,
    )

    q = np.array([[-5, -5, -1.0], [5, -5, -1.0], [5, 5, -1.0], [-5, 5, -1.0]])
    tris = np.array([q[[0, 1, 2]], q[[0, 2, 3]]])
    trimesh.Trimesh(tris.reshape(-1, 3), np.arange(6).reshape(-1, 3)).export(tmp_path / "f.obj")
    scene = parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "direct_path": False,
                "pose": {"position_m": [0, 0, 0]},
            },
            "simulation": {"max_range_m": 2.0, "bounces": 1, "snr_db": 60.0, "beam_deg": 180.0},
            "materials": [{"name": "floor", "reflection": 0.9}],
            "meshes": [{"file": "f.obj", "material": "floor"}],
            "points": [{"position_m": [1.0, 1.2, 0.0], "strength": 0.5}],
        },
        base_dir=tmp_path,
    )
    rec = Simulator(scene).simulate_pose(scene.sensor.poses[0])
    grid = P.Grid.degrees((-30, 30), (-90, 90), 3.0)
    settings = P.ProcessingSettings(grid=grid, energy_fraction=0.0, range_limits_m=(0.4, 1.9))
    image = P.acoustic_images(rec, ("das",), settings)["das"]
    peaks = image.peaks(-20.0)
    near_floor = np.abs(peaks.range_m - 1.0) < 0.05
    pole = np.abs(peaks.elevation_rad + np.pi / 2) < 1e-9
    assert (near_floor & pole).sum() == 1, "the floor below is one peak at the pole"
    down = near_floor & (peaks.elevation_rad < np.deg2rad(-60))
    assert down.sum() == 1, "and no other peak near the pole"
    res = image_resolution(rec, image, settings.window)
    edge = on_grid_edge(image, peaks)
    m = match_peaks(rec, peaks, res, edge)
    k = np.flatnonzero(near_floor & pole)[0]
    assert not edge[k] and m.kind[k] == "specular" and m.order[k] == 1
    # the point at azimuth 50 degrees, outside the +-30 degree grid: its flank peaks on
    # the grid's edge at its range, and no traced path lies within that peak's cell
    r_point = np.hypot(1.0, 1.2)
    side = edge & (np.abs(peaks.range_m - r_point) < 0.05) & (peaks.azimuth_rad > 0)
    assert side.any(), "no peak on the grid's edge at the point's range"
    for k in np.flatnonzero(side):
        assert m.index[k] == -1 and m.note[k] == EDGE_NOT_IN_CELL


def _truth(seen: bool) -> P.GroundTruth:
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(4, 3))
    extra = {}
    if seen:
        u = rng.normal(size=(4, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        first = pts.copy()
        first[0] = np.nan  # the direct path has no interaction (its last point: NaN)
        extra = {
            "delay_s": rng.uniform(1e-3, 1e-2, 4),
            "arrival_sensor": u,
            "apparent_position_sensor_m": pts + 1,
            "apparent_position_world_m": pts + 2,
            "first_point_m": first,
            "last_point_m": first,
            "object_index": np.array([-1, 0, 1, 1]),
            "object_names": ("wall/plaster", "point 0"),
        }
    kind = ["direct", "specular", "point", "point"]
    return P.GroundTruth(pts, pts, np.ones(4), np.array([0, 1, 1, 1]), kind, **extra)


@pytest.mark.parametrize("fmt", ["ours", "chirp"])
@pytest.mark.parametrize("seen", [True, False])
def test_truth_fields_round_trip_and_old_files_read_as_before(tmp_path, fmt, seen):
    """Written and read back, every field as it was; a truth without them (a file
    written before they existed) reads back without them."""
    truth = _truth(seen)
    rec = P.Recording(np.zeros((64, 64)), 500e3, P.paper_8x8(), P.paper_chirp(), truth=truth)
    path = tmp_path / "r.h5"
    if fmt == "ours":
        P.save_recording(path, rec)
    else:
        P.write_chirp(path, [rec])
    back = P.load_recording(path).truth
    assert back.has_apparent == seen
    for name in ("delay_s", "arrival_sensor", "apparent_position_sensor_m", "object_index"):
        if seen:  # stored as float32: a relative 6e-8
            np.testing.assert_allclose(getattr(back, name), getattr(truth, name), rtol=1e-7)
        else:
            assert getattr(back, name) is None
    if seen:
        np.testing.assert_allclose(back.first_point_m, truth.first_point_m, rtol=1e-7)
        # the last points are the last reflections (not stored), NaN for the direct path
        np.testing.assert_array_equal(back.last_point_m, truth.last_point_m)
        assert back.object_names == truth.object_names
        assert list(back.object_name()) == ["", "wall/plaster", "point 0", "point 0"]
    else:
        assert back.object_names == () and list(back.object_name()) == [""] * 4
    assert len(back.echoes()) == 3 and back.echoes().has_apparent == seen


def test_a_bad_object_index_is_refused():
    with pytest.raises(P.InputError, match="object_index 2"):
        P.GroundTruth(
            np.zeros((1, 3)),
            np.zeros((1, 3)),
            [1.0],
            [1],
            ["point"],
            object_index=[2],
            object_names=("a",),
        )


def _grid_dirs(az_deg, el_deg):
    el, az = np.meshgrid(np.deg2rad(el_deg), np.deg2rad(az_deg), indexing="ij")
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1)


def _at(r, az_deg):
    a = np.deg2rad(az_deg)
    return [r * np.cos(a), r * np.sin(a), 0.0]


def test_label_map_gives_each_cell_the_class_with_the_most_energy():
    """Worked by hand: a wall echo (object 0, order 1) at 1 m straight ahead, a
    two-bounce echo (object 1, order 2) at 1 m, 20 degrees left, and at 2 m three weak
    scatter paths of object 2 around 0 degrees whose sum beats one stronger path of
    object 3 there; a path 40 dB down labels nothing (30 dB dynamic range)."""
    from acousim.imaging.labels import label_map

    az, el = np.arange(-30, 31, 2.0), np.array([0.0])
    rng = np.arange(0.5, 2.6, 0.02)
    pos = [_at(1, 0), _at(1, 20), _at(2, -1), _at(2, 0), _at(2, 1), _at(2, 0.5), _at(2.4, -20)]
    energy = [1.0, 0.5, 0.2, 0.2, 0.2, 0.3, 1e-4]
    obj = [0, 1, 2, 2, 2, 3, 4]
    order = [1, 2, 1, 1, 1, 1, 1]
    lab = label_map(
        range_m=rng,
        directions=_grid_dirs(az, el).reshape(-1, 3),
        positions_m=pos,
        energy=energy,
        object_index=obj,
        order=order,
        cell=(0.1, np.deg2rad(10)),
        dynamic_range_db=30.0,
    ).reshaped((rng.size, el.size, az.size))

    def cell(r, a):
        return lab.object_index[np.argmin(abs(rng - r)), 0, np.argmin(abs(az - a))], lab.order[
            np.argmin(abs(rng - r)), 0, np.argmin(abs(az - a))
        ]

    assert cell(1.0, 0) == (0, 1)
    assert cell(1.0, 20) == (1, 2)
    assert cell(2.0, 0) == (2, 1)  # 0.6 summed against 0.3
    assert cell(2.4, -20) == (-1, -1)  # 40 dB down
    assert cell(1.5, 0) == (-1, -1)  # no path reaches it
    assert cell(1.0, -30) == (-1, -1)  # beyond one cell (10 degrees) of every path
    assert lab.object_index.dtype == np.int32 and lab.order.dtype == np.int16


def test_a_moving_sensor_sees_a_point_at_its_retarded_time(tmp_path):
    """A sensor driving at 2 m/s past a still point: the delay at the array centre is
    the retarded time at the moving centre (solved here by fixed point: emitted at
    the start of the emission from where the emitter is then, received where the
    centre has got to), and the apparent position lies along the arrival direction
    then, at half the path length."""
    v, point = np.array([2.0, 0.0, 0.0]), np.array([2.0, 0.5, 0.1])
    scene = parse_scene(
        {
            "sensor": {
                "array": "urtis_v1",
                "direct_path": False,
                "pose": {"position_m": [0, 0, 0], "velocity_m_s": v.tolist()},
            },
            "simulation": {"max_range_m": 3.0},
            "points": [{"position_m": point.tolist(), "strength": 1.0}],
        },
        base_dir=tmp_path,
    )
    pose = scene.sensor.poses[0]
    t = Simulator(scene).simulate_pose(pose).truth
    c = scene.environment.speed_of_sound_m_s
    array = scene.sensor.array
    e0, c0 = array.emitter_m, array.positions_m.mean(axis=0)  # the pose is the identity
    out = np.linalg.norm(point - e0) / c
    ts = out
    for _ in range(50):
        ts = out + np.linalg.norm(c0 + v * ts - point) / c
    u = (point - (c0 + v * ts)) / np.linalg.norm(point - (c0 + v * ts))
    (j,) = np.flatnonzero(t.kind == "point")
    assert abs(t.delay_s[j] - ts) <= 1e-10
    np.testing.assert_allclose(t.arrival_sensor[j], u, atol=1e-9)
    np.testing.assert_allclose(t.apparent_position_sensor_m[j], c0 + u * c * ts / 2, atol=1e-7)
    # the motion matters: more than 10 us from the frozen pose's delay
    frozen = (np.linalg.norm(point - e0) + np.linalg.norm(point - c0)) / c
    assert abs(ts - frozen) > 1e-5
    assert t.object_names[t.object_index[j]] == "point 0"
