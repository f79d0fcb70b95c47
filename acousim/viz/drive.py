"""The drive animation's frames: the 3D view beside the top view (fan), one figure laid
out once and reused for every frame.

Laying out and drawing a matplotlib figure (ticks, colour bar, legend, constrained
layout) costs most of a frame; only the two pictures, the fan's marks and the title
change between frames.  So the figure is drawn once without them (its background
kept), and each frame restores that background and draws only what changed
(matplotlib's blitting), the fan's pixels coming from a polar-to-pixel mapping
computed once (:func:`acousim.viz.fan.fan_raster`).
"""

from __future__ import annotations

import numpy as np

from processing import Image

from .fan import colorbar_label, draw_fan, fan_legend, fan_raster, fan_rgb, legend_inside

__all__ = ["DriveFigure"]


class DriveFigure:
    """One figure for every frame of a drive: the 3D view (left, titled with the
    recording) and the fan of one method (right) with its colour bar, one legend
    below both (the 3D view's entries and the fan's marks).

    view_shape : (H, W) of the 3D views.
    extent : the fan's view (:class:`acousim.viz.fan.FanRaster`), the same in every
        frame; max_range_m, dynamic_range_db as for :func:`acousim.viz.fan.draw_fan`.
    first : the first frame's image (lays the figure out).
    entries : the 3D view's legend entries (label, RGB).
    marks : the fan's mark kinds listed in the legend (every frame the same).
    """

    def __init__(
        self,
        *,
        view_shape: tuple[int, int],
        first: Image,
        extent: tuple[float, float, float, float],
        max_range_m: float,
        dynamic_range_db: float,
        entries=(),
        marks: set[str] = frozenset(),
        pixels: int = 600,
    ) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from .render3d import legend_handles

        self.extent, self.limit, self.dr, self.pixels = (
            extent,
            max_range_m,
            dynamic_range_db,
            pixels,
        )
        fig, (a, b) = plt.subplots(
            1, 2, figsize=(12, 5.8), gridspec_kw={"width_ratios": [1.2, 1]}, layout="constrained"
        )
        self.fig, self.ax_view, self.ax_fan = fig, a, b
        self.view = a.imshow(np.zeros((*view_shape, 3), np.uint8))
        a.axis("off")
        self.title = a.set_title(" ", fontsize=10)
        im = draw_fan(b, first, max_range_m, dynamic_range_db, pixels=pixels, extent=extent)
        self.fan = b.images[-1]
        b.set_title(f"{first.method}, top view", fontsize=9)
        fig.colorbar(im, ax=b, shrink=0.8, label=colorbar_label(dynamic_range_db))
        handles = legend_handles(entries, markersize=7) + fan_legend(set(marks), dynamic_range_db)
        legend_inside(fig, handles)
        fig.canvas.draw()  # the layout, once
        fig.set_layout_engine("none")
        for artist in (self.view, self.fan, self.title):
            artist.set_animated(True)
        fig.canvas.draw()
        self.background = fig.canvas.copy_from_bbox(fig.bbox)

    def frame(self, view: np.ndarray, image: Image, marks, title: str) -> np.ndarray:
        """One frame (H, W, 3) uint8: `view` (the 3D view), the fan of `image` with
        `marks` (:class:`acousim.viz.truth.TruthMarks` or None), `title` above the view."""
        canvas, a, b = self.fig.canvas, self.ax_view, self.ax_fan
        canvas.restore_region(self.background)
        self.view.set_data(view)
        raster = fan_raster(image, self.limit, self.dr, self.pixels, self.extent)
        self.fan.set_data(fan_rgb(raster, self.dr))
        self.title.set_text(title)
        a.draw_artist(self.view)
        a.draw_artist(self.title)
        b.draw_artist(self.fan)
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

    def close(self) -> None:
        import matplotlib.pyplot as plt

        plt.close(self.fig)
