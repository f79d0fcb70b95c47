"""The drive animation's frames: the plan view (or a 3D view) beside the top view
(fan), one figure laid out once and reused for every frame.

Laying out and drawing a matplotlib figure (ticks, colour bar, legend, constrained
layout) costs most of a frame; only the two pictures, the fan's marks and the title
change between frames.  So the figure is drawn once without them (its background
kept), and each frame restores that background, draws the plan's artists
(:class:`acousim.viz.plan.PlanPanel`) or writes the 3D view, writes the fan straight
into the canvas' pixels (nearest pixel, through maps computed once: for the fan,
each canvas pixel's polar cell, and per frame only each cell's colour from the colour
map, :func:`acousim.viz.fan.fan_levels`) and draws only the marks and the title
(matplotlib's blitting).

The GIF's frames share one palette (:func:`gif_palette`), made once, instead of one
per frame (Pillow's default for RGB frames, most of the encoding's time).
"""

from __future__ import annotations

from typing import Literal, get_args

import numpy as np

from acousim.viz.fan import (
    FanLevels,
    colorbar_label,
    draw_fan,
    fan_legend,
    fan_levels,
    legend_inside,
)
from acousim.viz.plan import PlanPanel, PlanScene
from processing import Image

__all__ = [
    "DriveFigure",
    "DriveView",
    "DRIVE_VIEWS",
    "check_drive_view",
    "drive_extent",
    "gif_palette",
    "write_gif",
]

DriveView = Literal["plan", "3d"]
"""The drive animation's left panel: "plan" (the scene cut at the sensor's height,
from above in the sensor's frame, drawn from arrays: :mod:`acousim.viz.plan`) or "3d"
(a 3D view behind and above the sensor, rendered per frame by VTK: about 60 ms of
CPU a frame more on a software renderer)."""
DRIVE_VIEWS: tuple[str, ...] = get_args(DriveView)


def check_drive_view(value: str, key: str = "view") -> DriveView:
    """`value` if it is one of :data:`DRIVE_VIEWS`, else an InputError naming `key`
    ("did you mean ...")."""
    from processing.base.settings import Setting, check

    check(Setting("str", choices=DRIVE_VIEWS), value, key)
    return value  # type: ignore[return-value]


#: the drive's panels are never narrower than this many times their depth (wider
#: than 0.8, a fan as wide as deep beside the 3D view outgrows the figure's height:
#: its title cut off, its axis label under the legend)
MIN_WIDTH_RATIO = 0.75


def drive_extent(
    extent: tuple[float, float, float, float], min_width_ratio: float = MIN_WIDTH_RATIO
) -> tuple[float, float, float, float]:
    """The drive's view (left, right, bottom, top) in metres of the sensor frame (y
    left +, so left > right): `extent` (the fan's, :func:`acousim.viz.fan.common_extent`)
    widened about its centre to at least `min_width_ratio` times its depth
    (top - bottom).  The fan of a wall straight ahead fits in half a metre; the plan
    on those axes would show a sliver of the scene and crowd its ticks."""
    left, right, bottom, top = (float(v) for v in extent)
    need = min_width_ratio * (top - bottom)
    if left - right >= need:
        return (left, right, bottom, top)
    centre = (left + right) / 2
    return (centre + need / 2, centre - need / 2, bottom, top)


#: colours of the GIF's palette taken as they are (the most frequent: background,
#: text, legend, flat faces); the rest of its 256 from an octree of the other pixels
EXACT_COLOURS = 64


class DriveFigure:
    """One figure for every frame of a drive: the left panel (titled with the
    recording) and the fan of one method (right) with its colour bar, one legend
    below both (the left panel's entries and the fan's marks).  The left panel is
    the plan view (:class:`acousim.viz.plan.PlanPanel`, drawn from arrays) or a 3D
    view rendered per frame (`left`).

    left : the left panel: a :class:`acousim.viz.plan.PlanScene` (the plan view on
        the fan's axes) or (H, W), the shape of the 3D views pasted into it.
    extent : the fan's view (:class:`acousim.viz.fan.FanRaster`), the same in every
        frame (widened to at least 3/4 of its depth: :func:`drive_extent`);
        max_range_m, dynamic_range_db as for :func:`acousim.viz.fan.draw_fan`.
    first : the first frame's image (lays the figure out).
    entries : the left panel's legend entries (label, RGB).
    marks : the fan's mark kinds listed in the legend (every frame the same).
    """

    def __init__(
        self,
        *,
        first: Image,
        extent: tuple[float, float, float, float],
        max_range_m: float,
        dynamic_range_db: float,
        left: PlanScene | tuple[int, int],
        entries=(),
        marks: set[str] = frozenset(),
        pixels: int = 600,
    ) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self.extent, self.limit, self.dr, self.pixels = (
            drive_extent(extent),
            max_range_m,
            dynamic_range_db,
            pixels,
        )
        ratios = [1, 1] if isinstance(left, PlanScene) else [1.2, 1]
        fig, (a, b) = plt.subplots(
            1, 2, figsize=(12, 5.8), gridspec_kw={"width_ratios": ratios}, layout="constrained"
        )
        self.fig, self.ax_view, self.ax_fan = fig, a, b
        handles = self._left(left, entries)
        self.title = a.set_title(" ", fontsize=10)
        im = draw_fan(b, first, max_range_m, dynamic_range_db, pixels=pixels, extent=self.extent)
        self.fan = b.images[-1]
        b.set_title(f"{first.method}, top view", fontsize=9)
        fig.colorbar(im, ax=b, shrink=0.8, label=colorbar_label(dynamic_range_db))
        legend_inside(fig, handles + fan_legend(set(marks), dynamic_range_db))
        # the background holds neither picture nor the title: hidden before the one
        # draw that lays the figure out (they are not part of its layout) and whose
        # pixels are kept
        self.title.set_animated(True)
        if self.plan is None:
            self.view.set_visible(False)
        self.fan.set_visible(False)
        fig.canvas.draw()  # the layout, once
        fig.set_layout_engine("none")
        self.background = fig.canvas.copy_from_bbox(fig.bbox)
        height = fig.canvas.get_width_height()[1]
        # where each picture's pixels go on the canvas: drawn straight from the arrays
        if self.plan is None:
            self.view_paste = _paste_map(a, self.view_shape, height, top_down=True)
        self.fan_paste = _paste_map(b, first_raster_shape(self.fan), height, top_down=False)
        self._fan_key: tuple | None = None
        self._fan_table_index = np.empty((0, 0), np.intp)

    def _left(self, left: PlanScene | tuple[int, int], entries) -> list:
        """Set the left panel up (the plan, or the 3D view's image of shape `left`);
        returns its legend handles."""
        from acousim.viz.render3d import legend_handles

        a = self.ax_view
        self.plan: PlanPanel | None = None
        if isinstance(left, PlanScene):
            self.plan = PlanPanel(a, extent=self.extent, scene=left, truth_range_db=self.dr)
            return self.plan.legend_entries(entries)
        self.view_shape = tuple(left)
        self.view = a.imshow(np.zeros((*self.view_shape, 3), np.uint8))
        a.axis("off")
        return legend_handles(entries, markersize=7)

    def frame(self, left, image: Image, marks, title: str) -> np.ndarray:
        """One frame (H, W, 3) uint8: `left` (the plan's
        :class:`acousim.viz.render3d.FrameContent`, or the 3D view (h, w, 3) uint8),
        the fan of `image` with `marks` (:class:`acousim.viz.truth.TruthMarks` or
        None), `title` above the left panel."""
        canvas, a, b = self.fig.canvas, self.ax_view, self.ax_fan
        canvas.restore_region(self.background)
        pixels = np.asarray(canvas.buffer_rgba())
        if self.plan is None:
            self.view_paste.paste(pixels, np.asarray(left)[..., :3])
        levels = fan_levels(image, self.limit, self.dr, self.pixels, self.extent)
        self.fan_paste.paste_colours(pixels, levels.colours(self.dr), self._fan_index(levels))
        if self.plan is not None:  # after the pixels written into the canvas
            self.plan.draw(left)
            for spine in a.spines.values():
                a.draw_artist(spine)
        self.title.set_text(title)
        a.draw_artist(self.title)
        if marks is not None:
            before = set(b.get_children())
            step = (self.extent[0] - self.extent[1]) / 40  # marks closer are one
            marks.draw(b, min_separation=step)
            for artist in [c for c in b.get_children() if c not in before]:
                b.draw_artist(artist)
                artist.remove()
        for spine in b.spines.values():  # the image covers the frame's inner half
            b.draw_artist(spine)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def _fan_index(self, levels: FanLevels) -> np.ndarray:
        """Per canvas pixel of the fan's box, its index into ``levels.colours()``
        (:func:`_fan_canvas_index`), made once for the drive's cells (every frame's,
        unless the range axis changes)."""
        key = (levels.r_edges.tobytes(), levels.a_edges.tobytes(), levels.db.size)
        if self._fan_key != key:
            self._fan_key = key
            self._fan_table_index = _fan_canvas_index(levels, self.fan_paste)
        return self._fan_table_index

    def close(self) -> None:
        import matplotlib.pyplot as plt

        plt.close(self.fig)


def first_raster_shape(image_artist) -> tuple[int, int]:
    """(rows, columns) of an AxesImage's array."""
    return tuple(image_artist.get_array().shape[:2])


class _Paste:
    """Nearest-pixel placement of a picture (h, w, 3) in a canvas box: the canvas
    rows `rows` (slice) and columns `cols` (slice) take the picture's rows `src_rows`
    (R,) and columns `src_cols` (C,)."""

    def __init__(self, rows: slice, cols: slice, src_rows: np.ndarray, src_cols: np.ndarray):
        self.rows, self.cols, self.src_rows, self.src_cols = rows, cols, src_rows, src_cols
        self._picked: dict[tuple[int, int], np.ndarray] = {}

    def paste(self, canvas: np.ndarray, picture: np.ndarray) -> None:
        """Write `picture` (h, w, 3) uint8 into `canvas` (H, W, 4), opaque."""
        self.paste_colours(canvas, picture.reshape(-1, 3), self.pick(picture.shape[:2]))

    def pick(self, shape: tuple[int, int]) -> np.ndarray:
        """Per canvas pixel of the box, the flat index of the picture's pixel (of a
        picture of `shape` (h, w)) it shows: (rows, columns) of the box (kept)."""
        if shape not in self._picked:
            self._picked[shape] = self.src_rows[:, None] * shape[1] + self.src_cols[None, :]
        return self._picked[shape]

    def paste_colours(self, canvas: np.ndarray, colours: np.ndarray, index: np.ndarray) -> None:
        """Write into the box of `canvas` (H, W, 4) the `colours` (N, 3) uint8 of
        `index` (the box's rows, columns) ints, opaque: each pixel one 32-bit word
        (its RGBA bytes as they lie in the canvas)."""
        rgba = np.empty((len(colours), 4), np.uint8)
        rgba[:, :3], rgba[:, 3] = colours, 255
        words = canvas.view(np.uint32)[..., 0]  # (H, W): a view of the canvas' pixels
        words[self.rows, self.cols] = rgba.view(np.uint32)[:, 0][index]


def _fan_canvas_index(levels: FanLevels, paste: _Paste) -> np.ndarray:
    """Per canvas pixel of the fan's box (`paste`), the index into
    :meth:`acousim.viz.fan.FanLevels.colours` of what it shows: the polar cell under
    the centre of the raster pixel it takes (:func:`acousim.viz.fan.fan_raster`'s
    nearest cell), else the floor (within the azimuth span) or white (outside it).
    The same picture as :func:`acousim.viz.fan.fan_rgb` of the raster, pasted."""
    cell, in_azimuth = levels.pixel_cells()
    n = levels.db.size
    index = np.where(cell >= 0, cell, np.where(in_azimuth, n, n + 1))
    return index.reshape(-1)[paste.pick(cell.shape)]


def _paste_map(ax, shape: tuple[int, int], height: int, *, top_down: bool) -> _Paste:
    """Where the AxesImage of `ax` (its array `shape` (h, w), drawn with nearest
    interpolation over its extent) lies on a canvas `height` pixels tall, and which of
    its pixels each canvas pixel shows (the pixel under its centre).  `top_down`:
    row 0 of the array is the top (origin "upper")."""
    h, w = shape
    image = ax.images[-1]
    left, right, bottom, top = image.get_extent()
    (x0, y0), (x1, y1) = ax.transData.transform([[left, bottom], [right, top]])
    box = ax.get_window_extent()  # the axes clip what lies outside them
    x0, x1 = sorted((x0, x1))
    y0, y1 = sorted((y0, y1))
    c0, c1 = int(round(max(x0, box.x0))), int(round(min(x1, box.x1)))
    r0, r1 = int(round(height - min(y1, box.y1))), int(round(height - max(y0, box.y0)))
    cols = np.arange(c0, c1) + 0.5
    ys = height - (np.arange(r0, r1) + 0.5)  # display y of each canvas row's centre
    src_cols = np.clip(((cols - x0) / (x1 - x0) * w).astype(int), 0, w - 1)
    up = (y1 - ys) if top_down else (ys - y0)
    src_rows = np.clip((up / (y1 - y0) * h).astype(int), 0, h - 1)
    return _Paste(slice(r0, r1), slice(c0, c1), src_rows, src_cols)


def gif_palette(frames, exact: int = EXACT_COLOURS, stride: int = 4):
    """One palette (a Pillow "P" image) for all `frames` ((N, H, W, 3) uint8, or a
    sequence of N (H, W, 3)), from every `stride`-th pixel of each: their `exact`
    most frequent colours as they are, and 256 - `exact` more from Pillow's fast
    octree of the other pixels."""
    from PIL import Image as PILImage

    pixels = np.concatenate([f[::stride, ::stride].reshape(-1, 3) for f in frames])
    key = pixels.astype(np.int64) @ np.array([1 << 16, 1 << 8, 1])
    values, counts = np.unique(key, return_counts=True)
    top = values[np.argsort(counts, kind="stable")[::-1][:exact]]
    colours = [np.stack([top >> 16, (top >> 8) & 255, top & 255], axis=-1)]
    rest = pixels[~np.isin(key, top)]
    if rest.size:
        octree = PILImage.fromarray(rest[None]).quantize(
            256 - top.size, method=PILImage.Quantize.FASTOCTREE
        )
        colours.append(np.reshape(octree.getpalette()[: 3 * (256 - top.size)], (-1, 3)))
    palette = PILImage.new("P", (1, 1))
    palette.putpalette(np.concatenate(colours).astype(np.uint8).ravel().tolist())
    return palette


def write_gif(path, frames, duration_ms: int) -> None:
    """`frames` ((N, H, W, 3) uint8, or a sequence of N (H, W, 3)) as a looping GIF
    at `path`, `duration_ms` (ms) per frame, every frame in one palette
    (:func:`gif_palette`; each pixel its nearest colour in it, no dithering)."""
    from PIL import Image as PILImage

    palette = gif_palette(frames)
    shown = [
        PILImage.fromarray(f).quantize(palette=palette, dither=PILImage.Dither.NONE) for f in frames
    ]
    shown[0].save(
        path, format="GIF", save_all=True, append_images=shown[1:], duration=duration_ms, loop=0
    )
