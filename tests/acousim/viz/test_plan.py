"""The drive's plan view: the scene cut at the sensor's height, in the sensor's frame.

The section is checked against trimesh's own mesh-plane intersection (a second
implementation) and against a cube's square worked out here; a drawn frame is read
back on its pixels: a wall placed in the world shows where the sensor sees it.
"""

import numpy as np
import pytest

from tests.acousim.imaging.synthetic import blob_image


def _segments_key(seg: np.ndarray) -> np.ndarray:
    """Segments (S, 2, 2) as sorted rows (each segment's ends in order), rounded."""
    s = np.round(np.asarray(seg, float), 9)
    ends = np.sort(s.reshape(-1, 2, 2).view([("x", float), ("y", float)]), axis=1)
    flat = ends.view(float).reshape(-1, 4)
    return flat[np.lexsort(flat.T[::-1])]


def test_a_cube_cut_through_its_middle_is_its_square():
    import trimesh

    from acousim.viz.plan import plane_section

    cube = trimesh.creation.box(extents=(2.0, 1.0, 3.0))  # centred on the origin
    seg = plane_section(cube.triangles)
    assert seg.shape[1:] == (2, 2) and len(seg) == 8  # two faces per side
    length = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1).sum()
    assert length == pytest.approx(2 * (2.0 + 1.0))
    on_side = np.isclose(np.abs(seg[..., 0]), 1.0) | np.isclose(np.abs(seg[..., 1]), 0.5)
    assert on_side.all()


def test_the_section_is_trimeshs_mesh_plane_intersection():
    import trimesh

    from acousim.viz.plan import plane_section

    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.3)
    mesh.apply_translation([0.2, -0.1, 0.37])  # the plane z = 0 cuts it off-centre
    want = trimesh.intersections.mesh_plane(mesh, [0, 0, 1], [0, 0, 0])
    got = plane_section(mesh.triangles)
    assert len(got) == len(want) > 20
    np.testing.assert_allclose(_segments_key(got), _segments_key(want[..., :2]), atol=1e-9)
    # every end point lies on the sphere's circle of the cut
    r = np.sqrt(1.3**2 - 0.37**2)
    radius = np.linalg.norm(got.reshape(-1, 2) - [0.2, -0.1], axis=1)
    assert radius.max() <= r + 1e-12 and radius.min() > r * np.cos(np.pi / 40)


def test_faces_above_below_or_touching_the_plane_give_no_segment():
    from acousim.viz.plan import plane_section

    above = [[0, 0, 0.1], [1, 0, 0.2], [0, 1, 0.3]]
    below = [[0, 0, -0.1], [1, 0, -0.2], [0, 1, -0.3]]
    touching = [[0, 0, 0.0], [1, 0, 0.2], [0, 1, 0.3]]  # a vertex on the plane
    lying = [[0, 0, 0.0], [1, 0, 0.0], [0, 1, 0.0]]  # in the plane
    assert plane_section(np.array([above, below, touching, lying], float)).shape == (0, 2, 2)


def test_a_point_ahead_of_a_turned_sensor_is_ahead_in_its_frame():
    from scipy.spatial.transform import Rotation

    from acousim.viz.plan import to_sensor_frame

    rot = Rotation.from_euler("ZYX", [120.0, 10.0, 5.0], degrees=True).as_matrix()
    pos = np.array([1.0, -2.0, 0.5])
    ahead = pos + 3.0 * rot[:, 0] + 0.5 * rot[:, 1]  # 3 m ahead, 0.5 m to its left
    np.testing.assert_allclose(to_sensor_frame(ahead, pos, rot), [3.0, 0.5, 0.0], atol=1e-12)


def _dark_grey(frame: np.ndarray) -> np.ndarray:
    """Pixels of the section's colour (dark grey, 64-71 of 255), as a mask."""
    from acousim.viz.plan import SECTION_COLOR

    want = np.array(SECTION_COLOR) * 255
    return (np.abs(frame.astype(float) - want) <= 12).all(axis=-1)


def _plan_points(ax, mask: np.ndarray) -> np.ndarray:
    """The pixels of `mask` (H, W) inside the plan's axes (two pixels clear of its
    frame) as points (N, 2) in its data coordinates: (y, x) in metres."""
    height = mask.shape[0]
    rows, cols = np.nonzero(mask)
    box = ax.get_window_extent()
    inside = (cols > box.x0 + 2) & (cols < box.x1 - 2) & (height - rows > box.y0 + 2)
    inside &= height - rows < box.y1 - 2
    return ax.transData.inverted().transform(np.column_stack([cols, height - rows])[inside])


@pytest.mark.parametrize("yaw_deg", [0.0, 90.0, -35.0])
def test_a_wall_ahead_of_the_sensor_is_drawn_at_its_distance_in_the_plan(yaw_deg):
    """A wall 2 m ahead of the sensor, across its axis, whatever way the sensor
    faces in the world: the plan's dark-grey pixels, mapped back through the axes,
    lie 2 m forward (within two pixels) and span the wall's width."""
    from scipy.spatial.transform import Rotation

    from acousim.viz.drive import DriveFigure
    from acousim.viz.plan import PlanScene
    from acousim.viz.render3d import FrameContent

    rot = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    pos = np.array([3.0, 1.0, 0.4])
    fwd, left, up = rot[:, 0], rot[:, 1], rot[:, 2]
    centre = pos + 2.0 * fwd
    corners = [centre + a * left + b * up for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    wall = np.array([[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]])
    img = blob_image([(1.0, 0.0, 0.0, 0.0)], ranges=np.arange(0.3, 2.5, 0.01))
    track = np.array([pos - 0.5 * fwd, pos])
    drive = DriveFigure(
        first=img,
        extent=(2.5, -2.5, 0.0, 2.6),
        max_range_m=2.5,
        dynamic_range_db=30.0,
        left=PlanScene(triangles=wall, track=track),
    )
    content = FrameContent(sensor_position=pos, sensor_axis=fwd, sensor_rotation=rot)
    frame = drive.frame(content, img, None, "recording 0")
    ax = drive.ax_view
    xy = _plan_points(ax, _dark_grey(frame))
    drive.close()
    metres_per_px = 5.0 / ax.get_window_extent().width
    xy = xy[np.hypot(*xy.T) > 0.8]  # not the sensor's arrow (black, its edges greyed)
    lateral, forward = xy[:, 0], xy[:, 1]
    assert len(forward) > 50
    assert np.abs(forward - 2.0).max() <= 2 * metres_per_px
    assert lateral.min() == pytest.approx(-1.0, abs=2 * metres_per_px)
    assert lateral.max() == pytest.approx(1.0, abs=2 * metres_per_px)


def test_a_narrow_drive_view_is_widened_about_its_centre_to_a_ratio_of_its_depth():
    from acousim.viz.drive import drive_extent

    # a wall 2 m straight ahead: the fan fits it in half a metre across
    left, right, bottom, top = drive_extent((0.3, -0.2, 0.0, 2.4), min_width_ratio=0.75)
    assert (left - right, (left + right) / 2) == pytest.approx((1.8, 0.05))
    assert (bottom, top) == (0.0, 2.4)
    wide = (2.8, -3.2, 0.0, 4.6)  # the corridor's: wider than deep, as it is
    assert drive_extent(wide) == wide


@pytest.mark.parametrize("left", ["plan", (480, 640)])
def test_the_drive_of_a_wall_straight_ahead_shows_its_section_0_9_m_each_side(left):
    """A 4 m wide wall 2 m ahead whose fan (a blob straight ahead) would fit in half
    a metre: the plan's dark-grey pixels reach +-0.9 m (the view 3/4 as wide as
    deep), both panels share the widened axes, and the fan's title and axis label
    stay in the figure, clear of the legend (beside the plan or the 3D view)."""
    from acousim.viz.drive import DriveFigure
    from acousim.viz.plan import PlanScene
    from acousim.viz.render3d import FrameContent

    a, b = 2.0, 2.0  # half width, half height
    corners = np.array([[2.0, -a, -b], [2.0, a, -b], [2.0, a, b], [2.0, -a, b]])
    wall = corners[[[0, 1, 2], [0, 2, 3]]]
    img = blob_image([(1.0, 0.0, 0.0, 0.0)], ranges=np.arange(0.3, 2.5, 0.01))
    drive = DriveFigure(
        first=img,
        extent=(0.25, -0.25, 0.0, 2.4),
        max_range_m=2.5,
        dynamic_range_db=30.0,
        left=PlanScene(triangles=wall, track=np.zeros((1, 3))) if left == "plan" else left,
        entries=[("image peaks", (1.0, 0.1, 0.1))] * 9,  # as tall a legend as a drive's
        marks={"in", "off", "behind", "weak"},
    )
    renderer = drive.fig.canvas.get_renderer()
    title = drive.ax_fan.title.get_window_extent(renderer)
    label = drive.ax_fan.xaxis.label.get_window_extent(renderer)
    assert title.y1 <= drive.fig.bbox.height
    assert label.y0 >= drive.fig.legends[0].get_window_extent(renderer).y1
    assert drive.ax_fan.get_xlim() == pytest.approx((0.9, -0.9))
    if left != "plan":
        drive.close()
        return
    content = FrameContent(sensor_position=np.zeros(3), sensor_axis=np.array([1.0, 0, 0]))
    frame = drive.frame(content, img, None, "recording 0")
    ax = drive.ax_view
    assert ax.get_xlim() == pytest.approx((0.9, -0.9))
    xy = _plan_points(ax, _dark_grey(frame))
    drive.close()
    xy = xy[np.abs(xy[:, 1] - 2.0) < 0.05]  # the wall's line
    metres_per_px = 1.8 / ax.get_window_extent().width
    assert xy[:, 0].max() >= 0.9 - 3 * metres_per_px
    assert xy[:, 0].min() <= -0.9 + 3 * metres_per_px


def test_a_rigs_track_is_one_per_sonar_with_a_gap_between():
    from acousim.viz.plan import drive_track

    pos = np.array([[0.0, 0.5, 0], [0.05, -0.5, 0], [0.1, 0.5, 0], [0.15, -0.5, 0]])
    got = drive_track(pos, ["left", "right", "left", "right"])
    np.testing.assert_array_equal(got[:2], pos[[0, 2]])
    assert np.isnan(got[2]).all()
    np.testing.assert_array_equal(got[3:], pos[[1, 3]])
    np.testing.assert_array_equal(drive_track(pos), pos)  # one sensor: as it is


def _track_grey(frame: np.ndarray) -> np.ndarray:
    from acousim.viz.plan import TRACK_COLOR

    want = np.array(TRACK_COLOR) * 255
    return (np.abs(frame.astype(float) - want) <= 10).all(axis=-1)


def test_the_plan_of_a_rig_draws_each_sonars_track_and_nothing_between_them():
    """Two sonars 1 m apart across a robot driving 1 m forward, firing in turn: in
    the left one's plan the track-grey pixels lie on its own line (y = 0) or its
    neighbour's (y = -1 m), none between (the zigzag from one to the other)."""
    from acousim.viz.drive import DriveFigure
    from acousim.viz.plan import PlanScene, drive_track
    from acousim.viz.render3d import FrameContent

    x = np.linspace(-1.0, 0.0, 20)
    pos = np.column_stack([x, np.where(np.arange(20) % 2, -0.5, 0.5), np.zeros(20)])
    names = ["left" if k % 2 == 0 else "right" for k in range(20)]
    img = blob_image([(1.0, 0.0, 0.0, 0.0)], ranges=np.arange(0.3, 2.5, 0.01))
    drive = DriveFigure(
        first=img,
        extent=(2.0, -2.0, -1.5, 2.5),
        max_range_m=2.5,
        dynamic_range_db=30.0,
        left=PlanScene(triangles=None, track=drive_track(pos, names)),
    )
    here = pos[18]  # the left sonar's last firing
    content = FrameContent(sensor_position=here, sensor_axis=np.array([1.0, 0, 0]))
    frame = drive.frame(content, img, None, "left")
    ax = drive.ax_view
    xy = _plan_points(ax, _track_grey(frame))
    labels = [h.get_label() for h in drive.plan.legend_entries([])]
    drive.close()
    xy = xy[(xy[:, 1] < -0.2) & (xy[:, 1] > -0.9)]  # behind the sensor, clear of it
    metres_per_px = 4.0 / ax.get_window_extent().width
    own = np.abs(xy[:, 0]) <= 2 * metres_per_px
    other = np.abs(xy[:, 0] + 1.0) <= 2 * metres_per_px
    assert own.sum() > 10 and other.sum() > 10
    assert (own | other).all()
    assert "the drive's track" in labels
    assert "scene cut at the sensor's height" not in labels  # no mesh: no section


def test_the_plans_legend_lists_no_section_without_faces_nor_a_track_for_a_still_sensor():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acousim.viz.plan import PlanPanel, PlanScene

    def labels(scene):
        fig, ax = plt.subplots()
        panel = PlanPanel(ax, extent=(1, -1, 0, 2), scene=scene, truth_range_db=30.0)
        out = [h.get_label() for h in panel.legend_entries([("image peaks", (1, 0, 0))])]
        plt.close(fig)
        return out

    still = np.zeros((5, 3))
    ring = "echo or peak hollow: over 30° above or below its plane"
    assert labels(PlanScene(triangles=None, track=still)) == ["image peaks", ring]
    wall = np.array([[[2.0, -1, -1], [2.0, 1, -1], [2.0, 0, 1]]])
    moved = np.array([[0.0, 0, 0], [0.1, 0, 0]])
    assert labels(PlanScene(triangles=wall, track=moved)) == [
        "scene cut at the sensor's height",
        "the drive's track",
        "image peaks",
        ring,
    ]


def _plan_without_a_mesh(entries=()):
    """A blob image and a drive figure whose plan has no mesh (the sensor still at
    the origin), 4 m wide and 2.5 m deep."""
    from acousim.viz.drive import DriveFigure
    from acousim.viz.plan import PlanScene

    img = blob_image([(1.0, 0.0, 0.0, 0.0)], ranges=np.arange(0.3, 2.5, 0.01))
    drive = DriveFigure(
        first=img,
        extent=(2.0, -2.0, 0.0, 2.5),
        max_range_m=2.5,
        dynamic_range_db=30.0,
        left=PlanScene(triangles=None, track=np.zeros((1, 3))),
        entries=entries,
    )
    return img, drive


def test_echoes_and_peaks_off_the_sensors_plane_are_hollow_in_the_plan():
    """An echo and a peak in the sensor's plane are filled discs where they lie; a
    floor echo and a peak 36 deg below it are rings (their centre pixel the
    background's), so a floor under the sensor does not look like an obstacle."""
    from acousim.viz.render3d import PEAK_COLOR, TRUTH_COLOR, FrameContent

    img, drive = _plan_without_a_mesh()
    # the sensor at the world's origin facing +x: world = sensor frame
    truth = np.array([[1.5, 1.0, 0.0], [1.0, -1.0, -1.0]])  # in plane; 35 deg below
    peaks = np.array([[1.8, 0.5, 0.3], [0.6, -0.3, -0.5]])  # 9 deg above; 37 deg below
    content = FrameContent(
        sensor_position=np.zeros(3),
        sensor_axis=np.array([1.0, 0, 0]),
        truth=truth,
        truth_level_db=np.zeros(2),
        peaks=peaks,
    )
    frame = drive.frame(content, img, None, "recording 0").astype(float)
    ax, height = drive.ax_view, frame.shape[0]
    drive.close()

    def at(point, colour, radius):
        """Pixels of `colour` within `radius` px of the sensor-frame `point`,
        and whether its centre pixel has that colour."""
        col, row = ax.transData.transform([point[1], point[0]])
        r, c = int(round(height - row)), int(round(col))
        near = np.abs(frame[r - radius : r + radius + 1, c - radius : c + radius + 1] - colour)
        match = (near <= 40).all(axis=-1)
        return match.sum(), match[radius - 1 : radius + 2, radius - 1 : radius + 2].all()

    cyan, red = np.array(TRUTH_COLOR) * 255, np.array(PEAK_COLOR) * 255
    n, centre = at(truth[0], cyan, 4)
    assert n > 40 and centre  # a filled disc
    n, centre = at(truth[1], cyan, 7)
    assert n > 8 and not centre  # a ring
    n, centre = at(peaks[0], red, 3)
    assert n > 20 and centre
    n, centre = at(peaks[1], red, 8)
    assert n > 8 and not centre


def test_the_plan_draws_the_lidars_points_near_the_sensors_plane_only():
    """A scan of a wall 2 m ahead (points from 0.5 m below to 0.5 m above the
    sensor) and of the floor 0.45 m below (a ring 1.5 m around): the green pixels
    lie on the wall's line, none on the floor's ring (the legend says the slice)."""
    from acousim.viz.render3d import LIDAR_COLOR, FrameContent

    y, z = np.meshgrid(np.linspace(-1.0, 1.0, 201), np.linspace(-0.5, 0.5, 21))
    wall = np.column_stack([np.full(y.size, 2.0), y.ravel(), z.ravel()])
    a = np.linspace(-np.pi / 3, np.pi / 3, 400)
    floor = np.column_stack([1.5 * np.cos(a), 1.5 * np.sin(a), np.full(a.size, -0.45)])
    img, drive = _plan_without_a_mesh(entries=[("LiDAR points", LIDAR_COLOR)])
    content = FrameContent(
        sensor_position=np.zeros(3),
        sensor_axis=np.array([1.0, 0, 0]),
        lidar=np.concatenate([wall, floor]),
    )
    frame = drive.frame(content, img, None, "recording 0").astype(float)
    ax = drive.ax_view
    labels = [h.get_label() for h in drive.plan.legend_entries([("LiDAR points", LIDAR_COLOR)])]
    drive.close()
    green = (np.abs(frame - np.array(LIDAR_COLOR) * 255) <= 40).all(axis=-1)
    xy = _plan_points(ax, green)  # the plan's (not the legend's dot)
    box = 4.0 / ax.get_window_extent().width  # metres a pixel
    on_wall = np.abs(xy[:, 1] - 2.0) <= 3 * box
    assert on_wall.sum() > 50 and on_wall.all()  # nothing on the floor's ring
    assert np.abs(xy[:, 0]).max() >= 1.0 - 3 * box
    assert "LiDAR points within 0.25 m of its plane" in labels
