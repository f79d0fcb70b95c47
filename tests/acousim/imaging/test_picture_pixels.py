"""The pictures read without asking, checked on their pixels: the energy gate's bins in
the colour map's floor colour, no stray white in a panel, the comparison's scales and
noise floors, the recording the stills show.

The images are built in the test (known blobs), and each expected colour or number is
worked out here (matplotlib's own colour map, numpy's median), not read from our code.
"""

import numpy as np
import pytest

import processing as P
from tests import REPO
from tests.acousim.imaging.synthetic import blob_image, hot

SCENES = REPO / "scenes"


def _canvas(fig) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def _box(ax, pic, inset=3):
    """The pixels (rows, cols slices) inside an axis' drawn box, `inset` px in."""
    b = ax.get_window_extent()
    h = pic.shape[0]
    rows = slice(int(np.ceil(h - b.y1)) + inset, int(h - b.y0) - inset)
    cols = slice(int(np.ceil(b.x0)) + inset, int(b.x1) - inset)
    return rows, cols


def test_gated_range_bins_are_drawn_in_the_floor_colour():
    import matplotlib
    import matplotlib.pyplot as plt

    from acousim.viz.fan import draw_fan

    # only the bins from 0.8 to 1.2 m survived the energy gate; the fan reaches 2 m
    img = blob_image([(1.0, 0.0, 0.0, 0.0)], ranges=np.arange(0.8, 1.2, 0.01))
    fig, ax = plt.subplots(figsize=(5, 4), dpi=100)
    draw_fan(ax, img, 2.0, 25.0, pixels=300, extent=(2.0, -2.0, 0.0, 2.0))
    pic = _canvas(fig)
    floor = np.round(np.array(matplotlib.colormaps["inferno"](0.0)[:3]) * 255)
    # pixels of the gated ring from 1.4 to 1.9 m, within 60 degrees of the axis
    to_px = ax.transData.transform
    y, x = np.meshgrid(np.linspace(-1.5, 1.5, 41), np.linspace(0.1, 1.9, 41))
    ring = (np.hypot(x, y) > 1.4) & (np.hypot(x, y) < 1.9) & (np.abs(np.arctan2(y, x)) < 1.0)
    px = to_px(np.column_stack([y[ring], x[ring]]))
    h = pic.shape[0]
    colours = pic[(h - px[:, 1]).astype(int), px[:, 0].astype(int)]
    assert len(colours) > 50
    assert np.abs(colours - floor).max() <= 1  # the floor colour: no grey ring
    # the ring between the gate's edge and the echo (quiet kept bins) is the same colour
    quiet = to_px([[0.0, 0.85]])[0]
    assert np.abs(pic[int(h - quiet[1]), int(quiet[0])] - floor).max() <= 1
    plt.close(fig)


def test_a_fan_panel_has_no_white_corner_past_the_imaged_range():
    """A view wider than the imaged range (its corners lie past the last range bin, as
    a corridor's fan fitted to its echoes) is not cut by a white triangle: within the
    azimuth span, past the range axis is no echo, the floor colour."""
    import matplotlib
    import matplotlib.pyplot as plt

    from acousim.viz.fan import draw_fan

    img = blob_image([(1.5, 0.0, 0.0, 0.0)], ranges=np.arange(0.3, 2.0, 0.01))
    fig, ax = plt.subplots(figsize=(5, 4), dpi=100)
    draw_fan(ax, img, 2.0, 25.0, pixels=300, extent=(2.0, -2.0, 0.0, 2.0))
    pic = _canvas(fig).astype(int)
    rows, cols = _box(ax, pic)
    panel = pic[rows, cols]
    h, w = panel.shape[:2]
    floor = np.round(np.array(matplotlib.colormaps["inferno"](0.0)[:3]) * 255)
    for corner in (panel[: h // 6, -w // 6 :], panel[: h // 6, : w // 6]):  # 2.5 m and more
        assert not (corner > 245).all(axis=2).any()  # no white
        assert np.abs(corner - floor).max() <= 1
    plt.close(fig)


def test_comparison_fans_share_one_scale_and_name_the_noise_floors():
    import matplotlib.pyplot as plt

    from acousim.compare.account import account
    from acousim.compare.comparison import (
        Alignment,
        Comparison,
        ComparisonArrays,
        MethodComparison,
        comparison_figure,
    )

    rng = np.arange(0.3, 2.5, 0.01)
    real = blob_image([(1.5, 10.0, 0.0, 0.0)], ranges=rng)
    sim = blob_image([(1.5, 10.0, 0.0, -6.0)], ranges=rng)  # 6 dB weaker
    edges = np.arange(0.0, 2.55, 0.05)
    gen = np.random.default_rng(1)
    prof_r = 1e-6 * (1 + 0.1 * gen.random(edges.size - 1))
    prof_s = 1e-8 * (1 + 0.1 * gen.random(edges.size - 1))
    prof_r[30] = prof_s[30] = 1.0
    # the last quarter (bins 37..49, 1.85-2.5 m) is 10 dB quieter than the clutter
    # before it: the median of every bin would read the clutter, not the floor
    prof_r[37:] /= 10.0
    prof_s[37:] /= 10.0
    empty = MethodComparison("das", (), (), (), (), (), 0.01)
    report = Comparison(Alignment(0.0, 0.0, 1.0), (1.0,), 0.05, (0.0,), {"das": empty})
    fig = comparison_figure(
        report, ComparisonArrays(edges, prof_r, prof_s, {"das": real}, {"das": sim})
    )
    fig.canvas.draw()
    fans = [ax for ax in fig.axes if ax.get_title().startswith(("real", "simulated"))]
    assert len(fans) == 2
    # a colour bar beside every fan, both over the same levels
    bars = [ax for ax in fig.axes if "dB re strongest cell of both" in ax.get_ylabel()]
    assert len(bars) == 2
    assert bars[0].get_ylim() == bars[1].get_ylim()
    # one scale: the simulated echo (6 dB weaker) is drawn darker than the real one
    pic = _canvas(fig).astype(float)
    peaks = []
    for ax in fans:
        rows, cols = _box(ax, pic)
        peaks.append(pic[rows, cols].sum(axis=2).max())
    assert peaks[1] < peaks[0] - 30
    # the profiles in dB re the real strongest bin, and both noise floors named with
    # their level: the median of the last quarter's bins, 10 log10(median / max), the
    # numbers the command prints (its account) and the span they are read over
    texts = [t.get_text() for t in fig.findobj(plt.Text)]
    assert any("dB re real strongest bin" in t for t in texts)
    said = account(report, ComparisonArrays(edges, prof_r, prof_s, {"das": real}, {"das": sim}))
    for name, prof, printed in (
        ("real", prof_r, said.floor_real_db),
        ("simulated", prof_s, said.floor_sim_db),
    ):
        expect = 10 * np.log10(np.median(prof[37:]) / prof_r.max())
        assert printed == pytest.approx(expect, abs=1e-9)
        assert expect < 10 * np.log10(np.median(prof) / prof_r.max()) - 5  # not the clutter
        assert any(t.startswith(name) and f"noise floor: {expect:.1f} dB" in t for t in texts)
    assert any("median over 1.85-2.50 m" in t for t in texts)
    assert (said.floor_from_m, said.floor_to_m) == pytest.approx((1.85, 2.5))
    plt.close(fig)


def test_scene3d_is_wide_and_its_legend_lies_outside_the_view_in_dark_text(tmp_path):
    import matplotlib.image as mpimg

    from acousim.viz.render3d import FrameContent, legend_entries, render_scene, view_figure

    content = FrameContent(np.zeros(3), np.array([1.0, 0.0, 0.0]), peaks=np.array([[2.0, 0, 0]]))
    view = render_scene(tmp_path / "s.png", content, triangles=None, title="s — recording 2")
    pic = mpimg.imread(tmp_path / "s.png")
    assert pic.shape[1] >= 1600
    # the legend: below the view (no pixel of the view under it), its text black
    fig = view_figure(view, legend_entries(with_truth=True), "t")
    fig.canvas.draw()
    (leg,) = fig.legends
    box, view_box = leg.get_window_extent(), fig.axes[0].get_window_extent()
    assert box.y1 <= view_box.y0 + 0.5
    assert all(t.get_color() in ("black", "k", (0, 0, 0, 1)) for t in leg.get_texts())
    import matplotlib.colors as mc

    for t in leg.get_texts():
        r, g, b = mc.to_rgb(t.get_color())
        assert 0.2126 * r + 0.7152 * g + 0.0722 * b < 0.3  # dark on the white ground
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_image_recording_chooses_the_recording_the_stills_show(tmp_path):
    import h5py  # noqa: F401

    from acousim.cli import main

    rec = P.Recording(np.zeros((64, 1500)), 500e3, P.paper_8x8(), P.paper_chirp())
    recs = []
    for k in range(4):
        pose = {"position_m": [k, 0, 0], "yaw_deg": 0, "pitch_deg": 0, "roll_deg": 0}
        meta = {"pose": {**pose, "time_s": 0.5 * k}, "scene": "s"}
        recs.append(P.Recording(rec.samples, 500e3, rec.array, rec.waveform, metadata=meta))
    P.save_recordings(tmp_path / "r.h5", recs)
    base = ["image", str(tmp_path / "r.h5"), "--no-3d", "--no-animation", "--no-data"]
    base += ["--method", "das"]
    seen = []
    import matplotlib.figure

    real = matplotlib.figure.Figure.savefig

    def spy(fig, *a, **k):
        seen.append(fig._suptitle.get_text() if fig._suptitle else "")
        return real(fig, *a, **k)

    import unittest.mock

    # every picture drawn in this process (no forked worker), where the spy sees it
    with unittest.mock.patch.object(matplotlib.figure.Figure, "savefig", spy):
        with unittest.mock.patch("acousim.core.forked._can_fork", lambda: False):
            assert main([*base, "--recording", "2", "--out", str(tmp_path / "a")]) == 0
    assert (tmp_path / "a" / "fan.png").is_file()
    assert seen and all("recording 2, t = 1.0 s" in t for t in seen)
    # a range: one set of pictures per recording, named by its index
    assert main([*base, "--recording", "1:3", "--out", str(tmp_path / "b")]) == 0
    names = {p.name for p in (tmp_path / "b").iterdir()}
    assert {"fan_1.png", "fan_2.png"} <= names  # (silent recordings: no el-az slice)
    assert "fan.png" not in names
    # a recording not imaged: one line naming the option and the index
    args = [*base, "--index", "0:2", "--recording", "3", "--out", str(tmp_path / "c")]
    assert main(args) == 2


def test_a_drive_frame_keeps_nothing_of_the_frame_before():
    """The animation draws each frame over the figure's kept background: a frame drawn
    after another is pixel for pixel the frame drawn first in a new figure."""
    from acousim.viz.drive import DriveFigure

    rng = np.arange(0.3, 2.5, 0.01)
    one = blob_image([(1.0, 30.0, 0.0, 0.0)], ranges=rng)
    two = blob_image([(2.0, -40.0, 0.0, 0.0)], ranges=rng)
    gen = np.random.default_rng(0)
    views = gen.integers(0, 255, (2, 120, 160, 3), dtype=np.uint8)
    kw = {"left": (120, 160), "extent": (2.5, -2.5, 0.0, 2.5), "max_range_m": 2.5}
    kw["dynamic_range_db"] = 30.0
    drive = DriveFigure(first=one, **kw)
    drive.frame(views[0], one, None, "recording 0, t = 0.0 s")
    after = drive.frame(views[1], two, None, "recording 1, t = 0.1 s")
    drive.close()
    fresh = DriveFigure(first=one, **kw)
    alone = fresh.frame(views[1], two, None, "recording 1, t = 0.1 s")
    fresh.close()
    assert after.shape == alone.shape and after.std() > 10
    np.testing.assert_array_equal(after, alone)


def test_a_drive_frame_is_what_matplotlib_draws_of_the_same_figure():
    """The frame's pictures are written straight into the canvas (nearest pixel):
    matplotlib's own drawing of the same figure (imshow) agrees within 2 levels of
    255 on at least 99% of the pixels (the rest: a pixel's shift at an edge)."""
    from acousim.viz.drive import DriveFigure
    from acousim.viz.fan import fan_raster, fan_rgb

    img = blob_image([(2.0, -40.0, 0.0, 0.0), (1.0, 20.0, 0, -5)], ranges=np.arange(0.3, 2.5, 0.01))
    yy, xx = np.mgrid[0:240, 0:320]
    view = np.stack([xx * 255 // 320, yy * 255 // 240, np.full_like(xx, 128)], -1).astype(np.uint8)
    extent = (2.5, -2.5, 0.0, 2.5)
    drive = DriveFigure(
        first=img, left=(240, 320), extent=extent, max_range_m=2.5, dynamic_range_db=30.0
    )
    fast = drive.frame(view, img, None, "recording 1").astype(int)
    drive.view.set_visible(True)
    drive.fan.set_visible(True)
    drive.view.set_data(view)
    drive.fan.set_data(fan_rgb(fan_raster(img, 2.5, 30.0, 600, extent), 30.0))
    drive.title.set_animated(False)
    drive.title.set_text("recording 1")
    full = _canvas(drive.fig).astype(int)
    drive.close()
    diff = np.abs(fast - full).max(axis=2)
    assert (diff <= 2).mean() >= 0.99
    assert hot(fast / 255).sum() > 20  # the echoes are drawn


def test_the_drive_gif_keeps_flat_colours_exactly_and_colour_maps_close(tmp_path):
    """The drive's GIF (one palette for every frame) read back with Pillow: the flat
    colours (background, text, legend) exactly as drawn, a colour map's smooth ramp
    (matplotlib's inferno, 1000 levels: more colours than a GIF holds) within a few
    levels of each pixel, every frame, the delay as asked."""
    import matplotlib
    from PIL import Image as PILImage

    from acousim.viz.drive import write_gif

    ramp = (matplotlib.colormaps["inferno"](np.linspace(0, 1, 1000))[:, :3] * 255).round()
    flat = np.array([[0, 0, 0], [200, 30, 30], [30, 160, 200], [90, 90, 90], [250, 210, 0]])
    frames = np.full((6, 90, 120, 3), 255, np.uint8)
    for k, f in enumerate(frames):
        for j, c in enumerate(flat):  # flat blocks moving from frame to frame
            f[5 + 12 * j : 15 + 12 * j, 4 + 3 * k : 30 + 3 * k] = c
        # the ramp over the right half, shifted by a frame-dependent offset
        idx = (np.add.outer(np.arange(90) * 5, np.arange(60) * 7) + 37 * k) % 1000
        f[:, 60:] = ramp[idx]
    write_gif(tmp_path / "d.gif", frames, 120)
    with PILImage.open(tmp_path / "d.gif") as gif:
        assert gif.n_frames == len(frames) and gif.info["duration"] == 120
        for k in range(gif.n_frames):
            gif.seek(k)
            got = np.asarray(gif.convert("RGB")).astype(int)
            np.testing.assert_array_equal(got[:, :60], frames[k, :, :60])
            err = np.abs(got[:, 60:] - frames[k, :, 60:])
            assert err.max() <= 16 and err.mean() < 2.5, (err.max(), err.mean())


def test_a_drive_frames_fan_pixels_are_their_polar_cells_colours_worked_out_one_by_one():
    """The drive's fan, drawn through one precomputed mapping of canvas pixels to
    polar cells and a colour table: every canvas pixel of the fan's box, worked out
    here one at a time (the raster pixel it takes, that pixel's centre in metres, its
    range and azimuth, the cell found by scanning the edges, the level's colour on
    matplotlib's inferno over 30 dB), is the frame's pixel."""
    import matplotlib

    from acousim.viz.drive import DriveFigure
    from acousim.viz.fan import fan_levels

    ranges = np.arange(0.3, 2.0, 0.01)
    img = blob_image([(1.5, -30.0, 0.0, 0.0), (0.8, 25.0, 0, -5)], ranges=ranges)
    gated = ranges[(ranges < 1.1) | (ranges > 1.3)]  # a gap the gate made: no data
    keep = np.isin(img.range_m, gated)
    img = P.Image(
        power=img.power[keep], range_m=img.range_m[keep], elevation_rad=img.elevation_rad,
        azimuth_rad=img.azimuth_rad, method=img.method, frequency_hz=img.frequency_hz,
        bin_range_m=img.bin_range_m,
    )  # fmt: skip
    extent, dr = (2.5, -2.5, -0.4, 2.6), 30.0  # behind the array: outside the view
    view = np.zeros((60, 80, 3), np.uint8)
    drive = DriveFigure(
        first=img, left=(60, 80), extent=extent, max_range_m=2.3, dynamic_range_db=dr,
        pixels=150,
    )  # fmt: skip
    frame = drive.frame(view, img, None, "recording 0")
    paste = drive.fan_paste
    drive.close()
    levels = fan_levels(img, 2.3, dr, 150, extent)  # the levels on their polar cells
    H, W = levels.height, levels.pixels
    lut = (matplotlib.colormaps["inferno"].resampled(256)(np.arange(256))[:, :3] * 255).round()
    y_left, y_right, x_lo, x_hi = extent
    r_edges, a_edges = levels.r_edges, levels.a_edges
    box = frame[paste.rows, paste.cols]
    checked = {"cell": 0, "floor": 0, "white": 0}
    for i in range(2, box.shape[0] - 2, 3):  # (the axes' frame drawn over the edges)
        for j in range(2, box.shape[1] - 2, 3):
            row, col = paste.src_rows[i], paste.src_cols[j]  # the raster pixel shown
            y = y_left + (col + 0.5) * (y_right - y_left) / W
            x = x_lo + (row + 0.5) * (x_hi - x_lo) / H
            r, az = np.hypot(x, y), np.arctan2(y, x)
            ri = [k for k in range(len(r_edges) - 1) if r_edges[k] < r <= r_edges[k + 1]]
            ai = [k for k in range(len(a_edges) - 1) if a_edges[k] < az <= a_edges[k + 1]]
            if not ai:
                want, kind = np.array([255, 255, 255]), "white"  # outside the field of view
            elif not ri or not np.isfinite(levels.db[ri[0], ai[0]]):
                want, kind = lut[0], "floor"  # no data: the floor colour
            else:
                level = levels.db[ri[0], ai[0]] / dr + 1.0
                want, kind = lut[min(max(int(level * 256), 0), 255)], "cell"
            assert np.array_equal(box[i, j], want), (i, j, kind, box[i, j], want)
            checked[kind] += 1
    assert min(checked.values()) > 50, checked
