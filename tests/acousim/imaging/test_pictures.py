"""The pictures read right: sides, scales, no-data cells, titles, slices, 3D views.

The images drawn here are built in the test (a known reflector direction), so each
check compares a pixel with geometry worked out by hand, not with our own output.
"""

import numpy as np
import pytest

import processing as P
from acousim.cli import main
from acousim.viz.fan import (
    draw_fan,
    elaz_figure,
    fan_raster,
    full_range_fan,
    pick_slices,
    truth_in_fan,
)
from tests import REPO
from tests.acousim.imaging.synthetic import blob_image, hot

SCENES = REPO / "scenes"


def test_a_reflector_on_the_left_is_drawn_left_with_positive_y(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # a reflector at y = +0.5 m (left), x = 1.0 m: azimuth atan2(0.5, 1) = +26.57 deg
    y, x = 0.5, 1.0
    img = blob_image([(np.hypot(x, y), np.rad2deg(np.arctan2(y, x)), 0.0, 0.0)])
    fig, ax = plt.subplots(figsize=(5, 4), dpi=100)
    draw_fan(ax, img, 2.0, 25.0, pixels=400)
    fig.canvas.draw()
    pic = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(float) / 255
    # the brightest (yellow-white) pixels of the inferno map
    bright = hot(pic)
    rows, cols = np.nonzero(bright)
    assert cols.size > 3
    h = pic.shape[0]
    to_px = ax.transData.transform
    centre_col = to_px([[0.0, 1.0]])[0, 0]
    left_col, expected_row = to_px([[y, x]])[0]
    # left of the centre line, where y = +0.5 m is (display rows grow downwards)
    assert cols.mean() < centre_col - 20
    assert abs(cols.mean() - left_col) < 6
    assert abs((h - rows.mean()) - expected_row) < 6
    # and the tick labels are true y values: +0.5 is labelled on the left of 0
    ticks = {t.get_text().replace("−", "-"): t.get_position()[0] for t in ax.get_xticklabels()}
    left = [float(k) for k in ticks if k and float(k) > 0]
    assert left, ticks
    assert to_px([[max(left), 0]])[0, 0] < centre_col
    plt.close(fig)


def test_elevation_azimuth_map_puts_a_left_echo_on_the_left(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    captured = []
    real_save = plt.Figure.savefig
    monkeypatch.setattr(
        plt.Figure, "savefig", lambda fig, *a, **k: captured.append(fig) or real_save(fig, *a, **k)
    )
    img = blob_image([(1.0, 40.0, 10.0, 0.0)])
    elaz_figure(img, tmp_path / "e.png", n_slices=1)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = captured[0]
    canvas = FigureCanvasAgg(fig)  # the figure was closed after saving
    canvas.draw()
    pic = np.asarray(canvas.buffer_rgba())[..., :3].astype(float) / 255
    ax = fig.axes[0]
    box = ax.get_window_extent()  # the map only, not its colour bar
    h = pic.shape[0]
    inside = np.zeros(pic.shape[:2], bool)
    inside[int(h - box.y1) : int(h - box.y0), int(box.x0) : int(box.x1)] = True
    rows, cols = np.nonzero(hot(pic) & inside)
    assert cols.size
    (c_left, r_up), (c_centre, r_mid) = ax.transData.transform([[40.0, 10.0], [0.0, 0.0]])
    # azimuth +40 (left) is drawn left of azimuth 0, elevation +10 above 0
    assert c_left < c_centre - 20 and abs(cols.mean() - c_left) < 6
    assert abs((h - rows.mean()) - r_up) < 6 and r_up > r_mid


def test_gated_range_bins_are_no_data_not_quiet():
    # only bins from 0.8 to 1.2 m survived the energy gate
    rng = np.arange(0.8, 1.2, 0.01)
    img = blob_image([(1.0, 0.0, 0.0, 0.0)], ranges=rng)
    r = fan_raster(img, 2.0, 25.0, pixels=200)
    y_left, y_right, x_lo, x_hi = r.extent
    xs = x_lo + (np.arange(r.db.shape[0]) + 0.5) * (x_hi - x_lo) / r.db.shape[0]
    ys = y_left + (np.arange(r.db.shape[1]) + 0.5) * (y_right - y_left) / r.db.shape[1]
    Y, X = np.meshgrid(ys, xs)
    dist = np.hypot(X, Y)
    fov = np.abs(np.arctan2(Y, X)) < np.deg2rad(85)
    assert r.no_data[fov & (dist > 1.4) & (dist < 1.9)].all()  # gated: no data
    assert np.isfinite(r.db[fov & (dist > 0.85) & (dist < 1.15)]).all()  # kept
    assert not r.no_data[fov & (dist > 0.85) & (dist < 1.15)].any()


@pytest.mark.parametrize("elevations", ["sorted", "shuffled"])
def test_top_view_is_each_kept_bins_maximum_over_the_horizontal_band(elevations):
    """full_range_fan against a loop written here: on the regular axis 0, 1 cm, ...,
    each kept bin (gated ones skipped) holds per azimuth the largest power over the
    elevations within the band (+-10 degrees); every other bin is NaN; whether the
    band's elevations lie side by side in the grid or not."""
    rnd = np.random.default_rng(5)
    el_deg = np.arange(-40.0, 41.0, 5.0)
    if elevations == "shuffled":
        el_deg = rnd.permutation(el_deg)
    kept = np.r_[20:35, 40:52]  # bins 0.20-0.34 m and 0.40-0.51 m
    img = P.Image(
        power=rnd.random((kept.size, el_deg.size, 7)),
        range_m=kept * 0.01,
        elevation_rad=np.deg2rad(el_deg),
        azimuth_rad=np.deg2rad(np.linspace(-60, 60, 7)),
        method="das",
        frequency_hz=40e3,
        bin_range_m=0.01,
    )
    axis, fan = full_range_fan(img, 0.6, np.deg2rad(10.0))
    np.testing.assert_allclose(axis, np.arange(61) * 0.01, atol=1e-12)
    want = np.full((61, 7), np.nan)
    for i, b in enumerate(kept):
        for a in range(7):
            want[b, a] = max(img.power[i, e, a] for e in range(el_deg.size) if abs(el_deg[e]) <= 10)
    np.testing.assert_array_equal(fan, want)


def _inside(artist, fig) -> bool:
    """The artist's drawn box lies within the figure's (from the layout, in pixels)."""
    b, f = artist.get_window_extent(), fig.bbox
    return b.x0 >= f.x0 - 0.5 and b.x1 <= f.x1 + 0.5 and b.y0 >= f.y0 - 0.5 and b.y1 <= f.y1 + 0.5


def test_fan_figure_states_its_scale_and_fits_the_extent():
    import matplotlib
    import matplotlib.pyplot as plt

    from acousim.viz.fan import DYNAMIC_RANGE_DB, make_fan_figure

    img = blob_image([(1.5, 20.0, 0.0, 0.0), (1.2, -30.0, 0.0, -6.0)])
    truth = np.array([[1.5 * np.cos(np.deg2rad(20)), 1.5 * np.sin(np.deg2rad(20)), 0.0]])
    fig = make_fan_figure({"das": img}, max_range_m=6.0, truth=truth, title="t")
    fig.canvas.draw()
    texts = [t.get_text() for t in fig.findobj(matplotlib.text.Text)]
    assert f"dB re strongest cell ({DYNAMIC_RANGE_DB:g} dB range)" in texts  # colour bar
    assert any(f"{DYNAMIC_RANGE_DB:g} dB dynamic range" in t for t in texts)
    # gated bins: the floor colour, no legend entry; the marks: traced echoes where seen
    assert not any("no data" in t for t in texts) and any("traced echo" in t for t in texts)
    ax = fig.axes[0]
    # echoes within 1.6 m: the view reaches ~2 m, not the 6 m of the scene
    assert ax.get_ylim()[1] < 2.2
    assert ax.get_xlim()[0] > ax.get_xlim()[1]  # y grows to the left
    assert all(_inside(leg, fig) for leg in fig.legends)
    plt.close(fig)


ALL_MARKS = np.array(
    [
        [1.0, 0.3, 0.0],  # in front, in the fan's elevation band
        [0.2, 0.0, -0.45],  # the floor below: 66 deg down, off the fan's slice
        [-1.0, 0.5, 0.0],  # behind the array: drawn at its mirror (1.0, 0.5, 0)
    ]
)


@pytest.mark.parametrize("n_methods", [1, 3, 5])
def test_legends_lie_within_the_figure(n_methods):
    """The legend of the fan (one to five panels) and of the el-az maps, with every
    mark in it, and the title lie inside the figure (both were cut at both sides of
    one panel)."""
    import matplotlib.pyplot as plt

    from acousim.viz.fan import make_elaz_figure, make_fan_figure
    from acousim.viz.truth import Reflectors

    img = blob_image([(1.04, 16.7, 0.0, 0.0), (0.49, 0.0, -40.0, -3.0), (1.12, 26.6, 0.0, -3)])
    methods = ["das", "capon-fbss", "music-fbss", "das-bb", "music"][:n_methods]
    truth = Reflectors(ALL_MARKS, np.array([0.0, -5.0, -25.0]))
    for fig in (
        make_fan_figure({m: img for m in methods}, max_range_m=3.0, truth=truth),
        make_elaz_figure(img, truth=truth, truth_tolerance_m=0.1),
    ):
        fig.canvas.draw()
        assert fig.legends, "no legend"
        for leg in fig.legends:
            assert _inside(leg, fig), (leg.get_window_extent(), fig.bbox)
        if fig._suptitle is not None:  # the title too (one panel cut it at both sides)
            assert _inside(fig._suptitle, fig), (fig._suptitle.get_window_extent(), fig.bbox)
        labels = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
        assert any("behind the array" in t for t in labels)
        plt.close(fig)


def test_marks_in_the_fan_off_its_slice_and_behind_the_array():
    from acousim.viz.truth import fan_marks

    m = fan_marks(ALL_MARKS, 5.0, np.deg2rad(30), (-np.pi / 2, np.pi / 2))
    assert list(m.mark) == ["in", "off", "behind"]
    # each at its slant range along its azimuth, as (y, x); the back one mirrored
    r0 = np.hypot(1.0, 0.3)
    np.testing.assert_allclose(m.xy[0], [0.3, 1.0], atol=1e-12)
    np.testing.assert_allclose(m.xy[1], [0.0, np.hypot(0.2, 0.45)], atol=1e-12)
    np.testing.assert_allclose(m.xy[2], [0.5, 1.0], atol=1e-12)
    assert np.hypot(*m.xy[0]) == pytest.approx(r0)
    # beyond the drawn range: not marked
    assert len(fan_marks(ALL_MARKS, 0.9, np.deg2rad(30), (-np.pi / 2, np.pi / 2))) == 1


def test_hundreds_of_echoes_leave_one_hollow_thin_mark_per_resolved_cell():
    """500 traced echoes (a corridor's scatter) in front of the array: a mark only
    for those within the dynamic range, at most one per resolved (range, azimuth)
    cell, the strongest of its cell; hollow and thin."""
    import matplotlib.pyplot as plt

    from acousim.viz.truth import Reflectors, fan_marks

    rng = np.random.default_rng(5)
    r = rng.uniform(0.5, 3.0, 500)
    az = rng.uniform(-1.2, 1.2, 500)
    pts = np.column_stack([r * np.cos(az), r * np.sin(az), np.zeros(500)])
    level = np.sort(rng.uniform(-60, 0, 500))[::-1]  # the strongest first
    cell = (0.1, np.deg2rad(10))
    m = fan_marks(Reflectors(pts, level, cell), 5.0, np.deg2rad(30), (-1.6, 1.6), 30.0)
    # worked out here: the cells of the echoes within 30 dB
    shown = level >= -30
    cells = {
        (int(np.floor(a / cell[0])), int(np.floor(b / cell[1])))
        for a, b in zip(r[shown], az[shown])
    }
    assert len(m) == len(cells) < shown.sum()
    got = np.hypot(*m.xy.T), np.arctan2(m.xy[:, 0], m.xy[:, 1])
    keys = list(zip(np.floor(got[0] / cell[0]).astype(int), np.floor(got[1] / cell[1]).astype(int)))
    assert len(set(keys)) == len(keys)  # one per cell
    # each the strongest of its cell
    for k, key in enumerate(keys):
        j = [
            i
            for i in range(500)
            if shown[i] and (int(np.floor(r[i] / cell[0])), int(np.floor(az[i] / cell[1]))) == key
        ][0]
        np.testing.assert_allclose(m.xy[k], [pts[j, 1], pts[j, 0]], atol=1e-9)
    fig, ax = plt.subplots()
    m.draw(ax)
    for coll in ax.collections:
        assert len(coll.get_facecolors()) == 0 and np.all(coll.get_linewidths() <= 0.6)
    plt.close(fig)


def test_thinned_marks_never_overlap_and_keep_the_strongest():
    """400 marks (strongest first) thinned to 0.1: no two kept nearer than that;
    each dropped one has a stronger kept one that near; the same marks as a greedy
    pass written out here, pair by pair."""
    from acousim.viz.truth import TruthMarks

    rng = np.random.default_rng(8)
    xy = rng.uniform(-1, 1, (400, 2)) * [1.0, 0.5]
    marks = TruthMarks(xy, np.full(400, "in"), np.zeros(400, bool)).thinned(0.1)
    d = np.hypot(*(marks.xy[:, None] - marks.xy[None]).transpose(2, 0, 1))
    assert np.all(d[np.triu_indices(len(marks), 1)] >= 0.1)
    kept: list[int] = []
    for i in range(400):  # the reference: each point against every one kept before it
        if all(np.hypot(*(xy[i] - xy[j])) >= 0.1 for j in kept):
            kept.append(i)
    np.testing.assert_array_equal(marks.xy, xy[kept])
    assert 30 < len(kept) < 400


def test_marks_on_an_elevation_azimuth_slice():
    from acousim.viz.truth import elaz_marks

    spans = ((-np.pi / 2, np.pi / 2), (np.deg2rad(-40), np.deg2rad(40)))
    floor = np.array([[0.2, 0.0, -0.45]])  # 0.492 m away, 66 deg down
    m = elaz_marks(floor, 0.49, 0.02, *spans)
    assert list(m.mark) == ["off"]  # outside the grid: at its bottom edge, azimuth 0
    np.testing.assert_allclose(m.xy[0], [0.0, -40.0], atol=1e-9)
    assert len(elaz_marks(floor, 0.60, 0.02, *spans)) == 0  # another slice's range
    back = np.array([[-1.0, 0.0, 0.2]])  # heard as its mirror: azimuth 0, el +11.3
    m = elaz_marks(back, float(np.linalg.norm(back)), 0.02, *spans)
    assert list(m.mark) == ["behind"]
    np.testing.assert_allclose(m.xy[0], [0.0, np.rad2deg(np.arctan2(0.2, 1.0))], atol=1e-9)


def test_every_picture_has_one_default_dynamic_range_and_prints_it():
    import inspect

    import matplotlib
    import matplotlib.pyplot as plt

    from acousim.export.rosbag import write_rosbag
    from acousim.imaging.run import ImagingOptions
    from acousim.viz.fan import DYNAMIC_RANGE_DB, make_elaz_figure, make_fan_figure

    assert ImagingOptions().dynamic_range_db == DYNAMIC_RANGE_DB
    for fn in (make_fan_figure, make_elaz_figure, write_rosbag, fan_raster, draw_fan):
        assert inspect.signature(fn).parameters["dynamic_range_db"].default == DYNAMIC_RANGE_DB
    img = blob_image([(1.5, 20.0, 0.0, 0.0)])
    for dr in (DYNAMIC_RANGE_DB, 17.0):  # a given one is printed too
        for fig in (
            make_fan_figure({"das": img}, dynamic_range_db=dr),
            make_elaz_figure(img, dynamic_range_db=dr),
        ):
            labels = [a.get_ylabel() for a in fig.axes]
            assert f"dB re strongest cell ({dr:g} dB range)" in labels
            texts = [t.get_text() for t in fig.findobj(matplotlib.text.Text)]
            assert any(f"{dr:g} dB dynamic range" in t for t in texts)
            plt.close(fig)


def test_floor_truth_is_drawn_at_its_slant_range():
    # a floor point 0.45 m straight below and a wall point on the left
    yx = truth_in_fan(np.array([[0.0, 0.0, -0.45], [0.0, 1.0, 0.0], [1.0, -1.0, 0.5]]))
    np.testing.assert_allclose(yx[0], [0.0, 0.45], atol=1e-12)
    np.testing.assert_allclose(yx[1], [1.0, 0.0], atol=1e-12)
    r = np.sqrt(2.25)
    np.testing.assert_allclose(yx[2], [-r / np.sqrt(2), r / np.sqrt(2)], atol=1e-12)


def test_slices_are_distinct_echoes_inside_the_grid():
    # a strong source beyond the grid's bottom edge (the floor at -90 deg) leaks onto
    # the -40 deg row; two echoes inside the grid, one of them doubled 2 cm apart
    img = blob_image(
        [
            (0.5, 0.0, -50.0, 20.0),
            (1.0, 30.0, 5.0, 0.0),
            (1.02, 31.0, 5.0, -1.0),
            (2.0, -20.0, 0.0, -5.0),
        ]
    )
    picks = pick_slices(img, 3)
    got = sorted(np.round(img.range_m[picks], 2))
    assert len(got) == 2  # the floor leak and the doubled echo are not slices
    assert abs(got[0] - 1.0) <= 0.02 and abs(got[1] - 2.0) <= 0.01


@pytest.mark.parametrize("index,expect", [("2", "recording 2"), (None, "recording 0")])
def test_titles_name_the_recording_and_no_time_for_a_single_pose(tmp_path, index, expect):
    from acousim.imaging.run import _title

    rec = P.Recording(np.zeros((64, 300)), 500e3, P.paper_8x8(), P.paper_chirp())
    pose = {"position_m": [0, 0, 0], "yaw_deg": 0, "pitch_deg": 0, "roll_deg": 0, "time_s": 0.0}
    single = P.Recording(
        rec.samples, 500e3, rec.array, rec.waveform, metadata={"pose": pose, "scene": "s"}
    )
    assert "t =" not in _title(single, 0)
    moving = dict(pose, time_s=3.0)
    traj = P.Recording(
        rec.samples, 500e3, rec.array, rec.waveform, metadata={"pose": moving, "scene": "s"}
    )
    assert _title(traj, 30, True) == "s — recording 30, t = 3.0 s"


def test_an_emulated_recording_without_a_scene_name_is_titled_emulated():
    from acousim.imaging.run import _title

    rec = P.Recording(np.zeros((64, 300)), 500e3, P.paper_8x8(), P.paper_chirp())
    meta = P.provenance_metadata("emulated")
    emulated = P.Recording(rec.samples, 500e3, rec.array, rec.waveform, metadata=meta)
    assert emulated.provenance.kind == "emulated" and emulated.provenance.scene is None
    assert _title(emulated, 4) == "emulated — recording 4"  # not "None (emulated)"
    named = {**meta, "scene": "wall"}
    wall = P.Recording(rec.samples, 500e3, rec.array, rec.waveform, metadata=named)
    assert _title(wall, 4) == "wall (emulated) — recording 4"


def test_image_index_titles_the_picture_with_its_recording(tmp_path, monkeypatch):
    import acousim.imaging.run as imaging

    seen = []
    real = imaging._title
    monkeypatch.setattr(imaging, "_title", lambda rec, i, *a: seen.append(i) or real(rec, i, *a))
    rec = P.Recording(np.zeros((64, 1500)), 500e3, P.paper_8x8(), P.paper_chirp())
    P.save_recordings(tmp_path / "r.h5", [rec, rec, rec])
    args = ["image", str(tmp_path / "r.h5"), "--index", "2", "--no-3d", "--method", "das"]
    assert main([*args, "--out", str(tmp_path / "o")]) == 0
    assert seen and set(seen) == {2}


def test_3d_render_of_a_real_recording_is_not_empty(tmp_path):
    from acousim.viz.render3d import PEAK_COLOR, SENSOR_COLOR, FrameContent, render_scene

    peaks = np.array([[2.0, 0.5, 0.2], [3.0, -0.8, 0.0]])
    pic = render_scene(
        tmp_path / "r.png",
        FrameContent(np.zeros(3), np.array([1.0, 0.0, 0.0]), peaks=peaks),
        triangles=None,
    )
    red = np.all(np.abs(pic / 255 - np.array(PEAK_COLOR)) < 0.25, axis=2)
    yellow = np.all(np.abs(pic / 255 - np.array(SENSOR_COLOR)) < 0.25, axis=2)
    grey = (np.ptp(pic, axis=2) < 10) & (pic.mean(axis=2) < 200)  # grid lines, labels
    assert red.sum() > 20  # the peaks are in view
    assert yellow.sum() > 100  # the sensor too
    assert grey.sum() > 2000  # and a grid in metres gives the scale
    assert (tmp_path / "r.png").is_file()


def test_3d_truth_below_the_threshold_is_not_drawn_and_stronger_is_larger(tmp_path):
    from scipy import ndimage

    from acousim.viz.render3d import TRUTH_COLOR, FrameContent, render_scene

    # three reflectors 2 m ahead, side by side: 0 dB, -20 dB, -40 dB (under -30 dB)
    truth = np.array([[2.0, 0.6, 0.0], [2.0, 0.0, 0.0], [2.0, -0.6, 0.0]])
    content = FrameContent(
        np.zeros(3),
        np.array([1.0, 0.0, 0.0]),
        truth=truth,
        truth_level_db=np.array([0.0, -20.0, -40.0]),
        peaks=np.array([[3.0, 0.0, 0.5]]),
    )
    pic = render_scene(None, content, triangles=None)
    cyan = np.all(np.abs(pic / 255 - np.array(TRUTH_COLOR)) < 0.3, axis=2)
    cyan[: int(0.2 * pic.shape[0]), : int(0.45 * pic.shape[1])] = False  # the legend
    labels, n = ndimage.label(cyan)
    sizes = ndimage.sum(cyan, labels, range(1, n + 1))
    blobs = sorted(
        zip(ndimage.center_of_mass(cyan, labels, range(1, n + 1)), sizes), key=lambda b: b[0][1]
    )
    blobs = [b for b in blobs if b[1] >= 2]
    assert len(blobs) == 2  # the -40 dB reflector is not drawn
    (left, s_left), (right, s_right) = blobs
    assert s_left > 1.5 * s_right  # 0 dB (y = +0.6, on the left) larger than -20 dB


def test_an_ertis_recording_is_imaged_by_default_by_the_methods_its_array_takes():
    """The default methods smooth over subarrays of a uniform rectangular array; an
    eRTIS (pseudo-random layout) is imaged by the same methods without smoothing
    when the defaults were kept: each image's strongest cell at the plate's echo
    (the scene's numbers: 3.218 m, 8 deg to the right, 2 deg up), within the
    grid's 2 deg and a range bin; asked for by name, a smoothed method is refused."""
    from acousim.bundled import find_scene
    from acousim.imaging.run import ImagingOptions, recording_images
    from acousim.scene import load_scene
    from acousim.simulator import Simulator
    from processing.base.errors import InputError

    rec = Simulator(load_scene(find_scene("ertis_sample"))).run()[0]
    options = ImagingOptions(min_range_m=1.0)
    images = recording_images(rec, options)
    assert sorted(images) == ["capon", "das", "music"]
    for method, img in images.items():
        r, e, a = np.unravel_index(np.argmax(img.power), img.power.shape)
        assert img.range_m[r] == pytest.approx(3.218, abs=0.05), method
        assert np.rad2deg(img.azimuth_rad[a]) == pytest.approx(-8.0, abs=2.0), method
        assert np.rad2deg(img.elevation_rad[e]) == pytest.approx(2.0, abs=2.0), method
    with pytest.raises(InputError, match="music-fbss cannot be used"):
        recording_images(rec, ImagingOptions(methods=("das", "music-fbss")))


def test_a_rigs_crosstalk_is_marked_where_it_shows_and_its_own_direct_path_not():
    # a rig's recording of sonar "a": its own direct path (not drawn), its wall echo
    # at 2 m ahead, sonar "b"'s call heard straight (0.8 m at azimuth -60 degrees)
    # and b's echo (3 m, +20 degrees): both of b's drawn as crosstalk, where seen,
    # levelled re the strongest echo (a's, amplitude 0.5: b's straight call +6 dB)
    from acousim.viz.truth import echo_points, fan_marks

    deg = np.deg2rad
    seen = np.array(
        [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.8 * np.cos(deg(-60)), 0.8 * np.sin(deg(-60)), 0.0],
            [3 * np.cos(deg(20)), 3 * np.sin(deg(20)), 0.0],
        ]
    )
    amp = np.array([5.0, 0.5, 1.0, 0.1])
    truth = P.GroundTruth(
        seen,
        seen,
        amp,
        np.array([0, 1, 0, 1]),
        ["direct", "specular", "direct", "specular"],
        emitter=np.array(["a", "a", "b", "b"]),
        delay_s=np.zeros(4),
        arrival_sensor=np.zeros((4, 3)),
        apparent_position_sensor_m=seen,
        apparent_position_world_m=seen,
    )
    found = echo_points(truth, np.zeros(3), 30.0, own="a")
    np.testing.assert_allclose(found.level_db, 20 * np.log10([1.0 / 0.5, 1.0, 0.1 / 0.5]))
    assert list(found.crosstalk) == [True, False, True]
    m = fan_marks(found, 5.0, deg(30), (-np.pi / 2, np.pi / 2))
    assert list(m.mark) == ["crosstalk", "in", "crosstalk"]
    np.testing.assert_allclose(m.xy[0], [0.8 * np.sin(deg(-60)), 0.8 * np.cos(deg(-60))])
    # a single sensor's truth (no emitters): no crosstalk, the direct path not drawn
    plain = P.GroundTruth(seen[:2], seen[:2], amp[:2], np.array([0, 1]), ["direct", "specular"])
    assert echo_points(plain, np.zeros(3), 30.0).crosstalk is None
    assert len(echo_points(plain, np.zeros(3), 30.0)) == 1
