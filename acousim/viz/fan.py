"""Fan images (azimuth x range, the top view of the paper's Figs. 13-14) and
elevation-azimuth maps, with matplotlib (Agg).  Files are written atomically.

Conventions of every picture here (the sensor frame: x forward, y left, z up;
azimuth positive towards +y, elevation positive towards +z):

- fan images are seen from above with x forward pointing up the page and the
  horizontal axis labelled in y, increasing to the LEFT (so the left of the sensor is
  on the left of the picture, and the tick labels are true y values);
- elevation-azimuth maps are seen from behind the sensor: azimuth increases to the
  left, elevation upwards;
- levels are dB relative to the strongest cell of each panel, shown over one
  dynamic range (:data:`DYNAMIC_RANGE_DB` unless given; every colour bar says how
  many dB); range bins the energy gate removed are drawn in the colour map's floor
  colour, like a quiet bin (the gate is a speed-up: it drops bins far below the
  strongest, so no rings of "no data" cross the picture); only what lies outside the
  field of view is white;
- ray-traced reflectors are marked in every picture, those off the picture's slice
  and those behind the array (at their mirror) with their own markers
  (:mod:`acousim.viz.truth`), and every legend lies inside the figure.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from processing import Image, to_db
from processing.base.atomic import atomic_path

__all__ = [
    "DYNAMIC_RANGE_DB",
    "FanLevels",
    "FanRaster",
    "NO_DATA_COLOR",
    "TRUTH_COLOR",
    "draw_fan",
    "elaz_figure",
    "fan_extent",
    "fan_figure",
    "fan_only",
    "fan_levels",
    "fan_raster",
    "floor_color",
    "full_range_fan",
    "make_elaz_figure",
    "make_fan_figure",
    "pick_slices",
    "truth_in_fan",
]

#: the dynamic range of every picture (fan, el-az maps, animation, the bag's fan
#: image) unless one is given (``--dynamic-range-db``); printed on every colour bar
DYNAMIC_RANGE_DB = 30.0
#: the fan collapses elevation over this band around the horizontal plane
FAN_ELEVATION_BAND_RAD = float(np.deg2rad(30.0))
CMAP = "inferno"
#: range bins removed by the energy gate: the colour map's floor (its value at 0,
#: black for inferno), as a quiet bin; :func:`floor_color` gives it for any map
NO_DATA_COLOR = (0.001462, 0.000466, 0.013866)
TRUTH_COLOR = "white"  # ray-traced reflectors: white circles
#: outside the field of view
OUTSIDE_COLOR = (1.0, 1.0, 1.0)


def floor_color(cmap: str = CMAP) -> tuple[float, float, float]:
    """The RGB (0-1) a colour map gives its lowest value: the colour of a level at or
    below the picture's dynamic range, and of range bins the energy gate removed."""
    import matplotlib as mpl

    return tuple(float(c) for c in mpl.colormaps[cmap](0.0)[:3])


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        # the figures are laid out by matplotlib's constrained layout: no "tight" pass
        fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".") or "png")
    return path


def full_range_fan(
    image: Image,
    max_range_m: float | None = None,
    elevation_limit_rad: float = FAN_ELEVATION_BAND_RAD,
) -> tuple[np.ndarray, np.ndarray]:
    """Top view on a regular range axis: (range_m (R',), power (R', A)).

    Each cell is the maximum over the elevations within ``elevation_limit_rad`` of the
    horizontal plane (near the poles every azimuth is the same direction, which would
    smear the view); range bins the energy gate dropped (or outside the imaged range
    limits) are NaN: no data.
    """
    step = image.bin_range_m or 0.01
    top = (
        max_range_m
        if max_range_m is not None
        else (float(image.range_m.max()) if image.range_m.size else step)
    )
    axis = np.arange(0.0, top + step / 2, step)
    fan = np.full((axis.size, image.azimuth_rad.size), np.nan)
    if image.range_m.size:
        idx = np.rint(image.range_m / step).astype(int)
        ok = (idx >= 0) & (idx < axis.size)
        band = np.abs(image.elevation_rad) <= elevation_limit_rad
        if not band.any():
            band = np.abs(image.elevation_rad) == np.abs(image.elevation_rad).min()
        power = image.power[:, _as_slice(band)]  # a view when the band is one run
        if not ok.all():
            power = power[ok]
        fan[idx[ok]] = np.fmax(fan[idx[ok]], power.max(axis=1))
    return axis, fan


def fan_only(image: Image, elevation_limit_rad: float = FAN_ELEVATION_BAND_RAD) -> Image:
    """`image` reduced to what its fan reads: (R, 2, A) cells instead of (R, E, A).

    Two adjacent elevations of the band (:func:`full_range_fan`'s), each holding the
    maximum over the band's elevations: the fan, its extent, levels and raster are
    those of `image`, and so is the grid's step (the cell the fan's marks are grouped
    by, :func:`acousim.imaging.matching.image_resolution`).  What an animation needs
    of a recording it does not draw as a still (its peaks found beforehand); `image`
    itself when no two adjacent elevations of the band are at the grid's smallest
    step (a band of one elevation, an uneven grid).
    """
    el = image.elevation_rad
    band = np.abs(el) <= elevation_limit_rad
    if el.size < 2 or not band.any():
        return image
    step = np.diff(el)
    pair = np.flatnonzero(band[:-1] & band[1:] & (step == step.min()))
    if pair.size == 0:
        return image
    j = int(pair[np.argmin(np.abs(el[pair]))])  # the pair nearest the horizontal plane
    top = image.power[:, _as_slice(band)].max(axis=1)  # (R, A)
    return Image(
        power=np.repeat(top[:, None, :], 2, axis=1),
        range_m=image.range_m,
        elevation_rad=el[j : j + 2].copy(),
        azimuth_rad=image.azimuth_rad,
        method=image.method,
        frequency_hz=image.frequency_hz,
        bin_range_m=image.bin_range_m,
    )


def _as_slice(mask: np.ndarray) -> slice | np.ndarray:
    """A boolean mask (N,) as the slice it selects when its True entries are one run
    (indexing by it then gives a view, not a copy), else the mask."""
    (on,) = np.nonzero(mask)
    if on.size and on[-1] - on[0] + 1 == on.size:
        return slice(int(on[0]), int(on[-1]) + 1)
    return mask


def truth_in_fan(points_sensor_m: np.ndarray) -> np.ndarray:
    """Ground-truth points (N, 3, sensor frame) placed where the fan draws their echo:
    at their slant range along their azimuth, as (y, x) (N, 2) in metres.

    The fan collapses elevation (range x azimuth), so a floor or ceiling point right
    below or above the sensor is drawn at its slant range straight ahead (azimuth 0),
    where the image shows that echo, not at the sensor.
    """
    p = np.asarray(points_sensor_m, float).reshape(-1, 3)
    r = np.linalg.norm(p, axis=1)
    az = np.arctan2(p[:, 1], p[:, 0])
    return np.column_stack([r * np.sin(az), r * np.cos(az)])


@dataclass(frozen=True)
class FanRaster:
    """The top view rasterised on square pixels.

    db : (H, W) dB relative to the strongest cell, floored at -dynamic range; NaN
        where there is no data or outside the field of view.
    no_data : (H, W) bool, inside the field of view but removed by the energy gate.
    extent : (y_left, y_right, x_bottom, x_top) in metres; y_left > y_right (y grows
        to the left), row 0 is the bottom (origin "lower").
    """

    db: np.ndarray
    no_data: np.ndarray
    extent: tuple[float, float, float, float]


def fan_extent(
    image: Image,
    max_range_m: float,
    dynamic_range_db: float,
    points_yx: np.ndarray | None = None,
    margin_m: float = 0.25,
) -> tuple[float, float, float, float]:
    """The part of the fan worth drawing: (y_left, y_right, x_bottom, x_top) in metres.

    It covers the cells within `dynamic_range_db` of the strongest, the given points
    (N, 2) as (y, x), and the sensor, plus `margin_m`, clipped to the field of view
    out to `max_range_m` (a corridor's echoes within 2 m are not lost in +-4.5 m axes).
    """
    rng, fan = full_range_fan(image, max_range_m)
    a = image.azimuth_rad
    pts = [np.zeros((1, 2))]
    if np.isfinite(fan).any() and np.nanmax(fan) > 0:
        db = to_db(np.nan_to_num(fan), floor_db=-np.inf)
        i, j = np.nonzero(db >= -dynamic_range_db)
        pts.append(np.column_stack([rng[i] * np.sin(a[j]), rng[i] * np.cos(a[j])]))
    if points_yx is not None and len(points_yx):
        p = np.asarray(points_yx, float)
        pts.append(p[np.hypot(p[:, 0], p[:, 1]) <= max_range_m])
    p = np.concatenate(pts)
    # the whole field of view out to max_range_m: the clip box
    ring = np.linspace(a.min(), a.max(), 181) if a.size else np.zeros(1)
    fy = np.concatenate([[0.0], max_range_m * np.sin(ring)])
    fx = np.concatenate([[0.0], max_range_m * np.cos(ring)])
    y_lo = max(p[:, 0].min() - margin_m, fy.min())
    y_hi = min(p[:, 0].max() + margin_m, fy.max())
    x_lo = max(p[:, 1].min() - margin_m, fx.min())
    x_hi = min(p[:, 1].max() + margin_m, fx.max())
    if y_hi - y_lo < 0.5:  # never narrower than half a metre
        c = (y_hi + y_lo) / 2
        y_lo, y_hi = c - 0.25, c + 0.25
    if x_hi - x_lo < 0.5:
        x_hi = x_lo + 0.5
    return (float(y_hi), float(y_lo), float(x_lo), float(x_hi))


def fan_raster(
    image: Image,
    max_range_m: float,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    pixels: int = 800,
    extent: tuple[float, float, float, float] | None = None,
    *,
    reference: float | None = None,
) -> FanRaster:
    """Rasterise the top view of `image` on `pixels` columns (nearest polar cell per
    pixel) after max-pooling range bins to the raster's resolution, so that no echo
    thinner than a pixel disappears.  `extent` as in :class:`FanRaster` (default: the
    whole field of view out to `max_range_m`); `reference` the power 0 dB stands for
    (default: the strongest cell drawn; two fans on one scale share one)."""
    levels = fan_levels(image, max_range_m, dynamic_range_db, pixels, extent, reference=reference)
    cell, in_azimuth = levels.pixel_cells()
    raster = np.full(cell.shape, np.nan)
    hit = cell >= 0
    raster[hit] = levels.db.ravel()[cell[hit]]
    # in the field of view without a level: bins the gate removed, or beyond the
    # range axis (the view's corners past the imaged range)
    no_data = in_azimuth & np.isnan(raster)
    return FanRaster(raster, no_data, levels.box)


@dataclass(frozen=True, eq=False)
class FanLevels:
    """The top view's levels on its polar cells, before rasterising: `db` (R', A) dB
    re the reference, floored at -dynamic range, NaN without data; the cells' edges
    in range `r_edges` (R' + 1,) m and azimuth `a_edges` (A + 1,) rad; the raster's
    `box` (as :class:`FanRaster`'s extent) and size (`height`, `pixels`)."""

    db: np.ndarray
    r_edges: np.ndarray
    a_edges: np.ndarray
    box: tuple[float, float, float, float]
    pixels: int
    height: int

    def pixel_cells(self) -> tuple[np.ndarray, np.ndarray]:
        """:func:`_pixel_cells` of these cells and raster (cached)."""
        key = (self.r_edges.tobytes(), self.a_edges.tobytes())
        return _pixel_cells(*key, self.box, self.pixels, self.height)

    def colours(self, dynamic_range_db: float, cmap: str = CMAP) -> np.ndarray:
        """Each cell's colour as :func:`fan_rgb` gives it, then the colours of a pixel
        in the azimuth span on no cell (the floor) and of one outside it (white):
        (R' A + 2, 3) uint8, indexed as :meth:`pixel_cells`' flat cells."""
        level = np.nan_to_num(self.db.ravel(), nan=-dynamic_range_db) / dynamic_range_db + 1.0
        lut = _lut(cmap)
        return np.concatenate(
            [
                lut[np.clip((level * 256).astype(int), 0, 255)],
                lut[:1],  # the floor: no data within the azimuth span
                np.round(np.multiply(OUTSIDE_COLOR, 255)).astype(np.uint8)[None],
            ]
        )


def fan_levels(
    image: Image,
    max_range_m: float,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    pixels: int = 800,
    extent: tuple[float, float, float, float] | None = None,
    *,
    reference: float | None = None,
) -> FanLevels:
    """The levels :func:`fan_raster` rasterises (the same arguments): the top view
    max-pooled to about one range bin per pixel, in dB."""
    rng, fan = full_range_fan(image, max_range_m)
    r_edges, a_edges = _edges(rng), _edges(image.azimuth_rad)
    if extent is None:
        A, Rg = np.meshgrid(a_edges, np.clip(r_edges, 0, None))
        Yw, Xw = Rg * np.sin(A), Rg * np.cos(A)
        extent = (float(Yw.max()), float(Yw.min()), float(Xw.min()), float(Xw.max()))
    y_left, y_right, x_lo, x_hi = extent
    width = max(y_left - y_right, 1e-9)
    height = max(int(round(pixels * (x_hi - x_lo) / width)), 1)
    # max-pool range bins to about one per pixel
    pixel_m = width / pixels
    k = max(int(pixel_m / (rng[1] - rng[0])) if rng.size > 1 else 1, 1)
    if k > 1:
        pad = -rng.size % k
        padded = np.pad(fan, ((0, pad), (0, 0)), constant_values=np.nan)
        with np.errstate(invalid="ignore"):
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks: no data
                fan = np.nanmax(padded.reshape(-1, k, fan.shape[1]), axis=1)
        step = rng[1] - rng[0]
        rng = rng[0] + step * (k * np.arange(fan.shape[0]) + (k - 1) / 2)
        r_edges = _edges(rng)
    finite = np.isfinite(fan)
    ref = float(fan[finite].max()) if finite.any() else 0.0
    ref = ref if reference is None else float(reference)
    db = np.where(finite, to_db(np.nan_to_num(fan), ref or None, -dynamic_range_db), np.nan)
    box = (float(y_left), float(y_right), float(x_lo), float(x_hi))
    return FanLevels(db, r_edges, a_edges, box, pixels, height)


@functools.lru_cache(maxsize=4)
def _lut(cmap: str) -> np.ndarray:
    """The colour map's 256 colours (256, 3) uint8, as :func:`fan_rgb` takes them."""
    import matplotlib as mpl

    lut = (mpl.colormaps[cmap].resampled(256)(np.arange(256))[:, :3] * 255).round()
    lut = lut.astype(np.uint8)
    lut.flags.writeable = False
    return lut


@functools.lru_cache(maxsize=8)
def _pixel_cells(
    r_edges: bytes, a_edges: bytes, box: tuple[float, float, float, float], pixels: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """The polar cell under each pixel's centre of a (height, pixels) raster over `box`
    (as :class:`FanRaster`'s extent) for cell edges in range (R + 1,) and azimuth
    (A + 1,) given as float64 bytes: (flat index into (R, A), -1 where none (H, W);
    the pixel lies within the azimuth span (H, W) bool).  Cached: an animation's
    frames share one mapping."""
    r, a = np.frombuffer(r_edges), np.frombuffer(a_edges)
    y_left, y_right, x_lo, x_hi = box
    PY, PX = np.meshgrid(_centres(y_left, y_right, pixels), _centres(x_lo, x_hi, height))
    i = np.searchsorted(r, np.hypot(PX, PY)) - 1
    j = np.searchsorted(a, np.arctan2(PY, PX)) - 1
    in_azimuth = (j >= 0) & (j < a.size - 1)
    inside = in_azimuth & (i >= 0) & (i < r.size - 1)
    cell = np.where(inside, i * (a.size - 1) + j, -1)
    cell.flags.writeable = in_azimuth.flags.writeable = False
    return cell, in_azimuth


def fan_rgb(raster: FanRaster, dynamic_range_db: float, cmap: str = CMAP) -> np.ndarray:
    """The colours of a :class:`FanRaster`: (H, W, 3) uint8, row 0 the bottom.

    Levels map linearly onto `cmap` from -`dynamic_range_db` (its floor) to 0 dB;
    range bins the energy gate removed take the floor colour (a quiet bin), pixels
    outside the field of view are white (:data:`OUTSIDE_COLOR`)."""
    level = np.nan_to_num(raster.db, nan=-dynamic_range_db) / dynamic_range_db + 1.0
    rgb = _lut(cmap)[np.clip((level * 256).astype(int), 0, 255)]
    rgb[np.isnan(raster.db) & ~raster.no_data] = np.round(np.multiply(OUTSIDE_COLOR, 255))
    return rgb


def draw_fan(
    ax,
    image: Image,
    max_range_m: float,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    pixels: int = 800,
    extent: tuple[float, float, float, float] | None = None,
    *,
    reference: float | None = None,
):
    """Draw the top view of an image on a matplotlib axis (x forward up, y to the left:
    the horizontal axis is y in metres and increases leftwards).  Returns a
    ScalarMappable of the colours (for a colour bar).  See :func:`fan_raster` for
    `extent` and `reference`."""
    import matplotlib as mpl

    r = fan_raster(image, max_range_m, dynamic_range_db, pixels, extent, reference=reference)
    ax.imshow(
        fan_rgb(r, dynamic_range_db), origin="lower", extent=r.extent, interpolation="nearest"
    )
    norm = mpl.colors.Normalize(-dynamic_range_db, 0.0)
    im = mpl.cm.ScalarMappable(norm=norm, cmap=mpl.colormaps[CMAP])  # for a colour bar
    ax.set_xlim(r.extent[0], r.extent[1])
    ax.set_ylim(r.extent[2], r.extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("y (m), left +")
    ax.set_ylabel("x forward (m)")
    return im


def fan_figure(images: Mapping[str, Image], path: str | Path, **kw) -> Path:
    """Write :func:`make_fan_figure` (same keywords) to `path` (atomically)."""
    plt = _plt()
    fig = make_fan_figure(images, **kw)
    out = _save(fig, path)
    plt.close(fig)
    return out


def make_fan_figure(
    images: Mapping[str, Image],
    *,
    max_range_m: float | None = None,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    title: str | None = None,
    truth=None,
):
    """One fan panel per method, side by side (x forward, y to the left), each with a
    colour bar in dB; one legend, inside the figure, for the traced reflectors'
    marks.  Returns the matplotlib Figure.

    max_range_m : the farthest range that may be drawn (the scene's range); the view
        is fitted to the echoes within the dynamic range and the marks inside it.
    truth : optional traced reflectors (:class:`acousim.viz.truth.Reflectors`, or
        points (N, 3) in the sensor frame from the array centre, m), marked at
        their slant range along their azimuth (:func:`acousim.viz.truth.fan_marks`).
    """
    plt = _plt()
    n = len(images)
    cols = n if n <= 4 else int(np.ceil(n / 2))
    rows = int(np.ceil(n / cols))
    if max_range_m is None:
        max_range_m = max(
            (float(im.range_m.max()) for im in images.values() if im.range_m.size), default=1.0
        )
    marks = _marks(images, truth, max_range_m, dynamic_range_db)
    extent = common_extent(
        list(images.values()), max_range_m, dynamic_range_db, marks.xy if marks else None
    )
    if marks is not None:  # one mark per 1/40 of the view's width, the strongest
        marks = marks.thinned((extent[0] - extent[1]) / 40)
    aspect = (extent[3] - extent[2]) / (extent[0] - extent[1])
    panel_w = 4.2
    fig, axes = plt.subplots(
        rows,
        cols,
        figsize=(panel_w * cols, min(max(panel_w * aspect, 2.4), 9.0) * rows + 1.2),
        squeeze=False,
        layout="constrained",
    )
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    drawn: set[str] = set()
    for ax, (method, img) in zip(axes.ravel(), images.items()):
        im = draw_fan(ax, img, max_range_m, dynamic_range_db, extent=extent)
        if marks is not None:
            drawn |= marks.draw(ax)
        ax.set_title(method)
        fig.colorbar(im, ax=ax, shrink=0.85, label=colorbar_label(dynamic_range_db))
    legend_inside(fig, fan_legend(drawn, dynamic_range_db))
    band = np.rad2deg(FAN_ELEVATION_BAND_RAD)
    sep = "; " if cols > 1 else ";\n"  # one panel: too narrow for the line (it was cut)
    head = (
        f"top view, {dynamic_range_db:g} dB dynamic range{sep}elevation within "
        f"±{band:g}° is this slice"
    )
    fitted_title(fig, f"{title}\n{head}" if title else head)
    return fig


def fitted_title(fig, text: str, fontsize: float = 10.0) -> None:
    """`text` as the figure's title, each line wrapped at its "; " and ", " where it
    is wider than the figure (a one-panel figure cut it at both sides)."""
    import textwrap

    chars = max(20, int(fig.get_figwidth() * 72 / (0.6 * fontsize)))  # ~average glyph
    lines = [textwrap.fill(line, chars, break_on_hyphens=False) for line in text.split("\n")]
    fig.suptitle("\n".join(lines), fontsize=fontsize)


def _marks(images: Mapping[str, Image], truth, max_range_m: float, dynamic_range_db: float):
    """The traced reflectors' fan marks over the first image's azimuth span (None
    without truth or images)."""
    from acousim.viz.truth import fan_marks

    if truth is None or not len(truth) or not images:
        return None
    az = next(iter(images.values())).azimuth_rad
    span = (float(az.min()), float(az.max())) if az.size else (-np.pi / 2, np.pi / 2)
    return fan_marks(truth, max_range_m, FAN_ELEVATION_BAND_RAD, span, dynamic_range_db)


def common_extent(images, max_range_m: float, dynamic_range_db: float, points_yx=None):
    """One :func:`fan_extent` covering every image (panels or frames side by side keep
    the same axes)."""
    e = np.array(
        [fan_extent(im, max_range_m, dynamic_range_db, points_yx) for im in images]
        or [(1.0, -1.0, 0.0, 1.0)]
    )
    return (e[:, 0].max(), e[:, 1].min(), e[:, 2].min(), e[:, 3].max())


def fan_legend(drawn: set[str], dynamic_range_db: float) -> list:
    """A fan's legend entries: the marks drawn (the energy gate's removed bins are
    the floor colour: nothing to explain)."""
    from acousim.viz.truth import legend_handles

    return list(legend_handles(drawn, dynamic_range_db))


def colorbar_label(dynamic_range_db: float, joint: bool = False) -> str:
    """Every colour bar's label: the unit and the dynamic range shown (`joint`: the
    reference is the strongest cell of the panels drawn on one scale)."""
    of = " of both" if joint else ""
    return f"dB re strongest cell{of} ({dynamic_range_db:g} dB range)"


def legend_inside(fig, handles, fontsize: float = 8):
    """A legend below the panels that fits the figure's width: as many columns as fit
    (down to one), and a wider figure only when one column is still too wide."""
    if not handles:
        return None
    renderer = fig.canvas.get_renderer()
    for ncols in range(min(len(handles), 3), 0, -1):
        leg = fig.legend(
            handles=handles, loc="outside lower center", ncols=ncols, fontsize=fontsize
        )
        width = leg.get_window_extent(renderer).width
        if width <= 0.96 * fig.bbox.width:
            return leg
        if ncols > 1:
            leg.remove()
    fig.set_figwidth(width / fig.dpi / 0.9)
    return leg


def _centres(lo: float, hi: float, n: int) -> np.ndarray:
    """Centres (n,) of n equal cells from lo to hi (hi < lo gives a decreasing axis)."""
    return lo + (np.arange(n) + 0.5) * (hi - lo) / n


def _edges(x: np.ndarray) -> np.ndarray:
    """Cell edges around centres x (n,): (n + 1,)."""
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = (x[1:] + x[:-1]) / 2
    return np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])


def pick_slices(
    image: Image, n: int = 3, min_separation_m: float = 0.1, dynamic_range_db: float = 40.0
) -> list[int]:
    """Range bins (indices into ``image.range_m``) of up to `n` distinct echoes: the
    strongest local maxima of the 3D image that lie inside the grid (not on its
    elevation or azimuth border, where a source outside the grid, such as the floor at
    -90 deg, leaks in), at least `min_separation_m` apart in range.  Falls back to
    the strongest bins when the image has no interior maximum within
    `dynamic_range_db` of the strongest cell."""
    p = image.power
    if p.size == 0:
        return []
    from scipy.ndimage import maximum_filter

    floor = p.max() * 10 ** (-dynamic_range_db / 10)
    local = (p >= maximum_filter(p, size=3, mode="nearest")) & (p > 0) & (p >= floor)
    E, A = p.shape[1:]
    border = np.zeros((E, A), bool)
    if E > 2:
        border[[0, -1], :] = True
    if A > 2:
        border[:, [0, -1]] = True
    local &= ~border[None]
    r, e, a = np.nonzero(local)
    order = np.argsort(p[r, e, a])[::-1]
    cand = list(r[order])
    if not cand:
        cand = list(np.argsort(p.reshape(p.shape[0], -1).max(axis=1))[::-1])
    picks: list[int] = []
    for i in cand:
        if all(abs(image.range_m[i] - image.range_m[j]) >= min_separation_m for j in picks):
            picks.append(int(i))
        if len(picks) == n:
            break
    return picks


def elaz_figure(image: Image, path: str | Path, **kw) -> Path:
    """Write :func:`make_elaz_figure` (same keywords) to `path` (atomically)."""
    plt = _plt()
    fig = make_elaz_figure(image, **kw)
    out = _save(fig, path)
    plt.close(fig)
    return out


def _elaz_panel(ax, image: Image, r: int, dynamic_range_db: float):
    """Draw the elevation-azimuth map of range bin `r` on `ax` (seen from behind the
    sensor); returns the AxesImage (for a colour bar)."""
    az, el = np.rad2deg(image.azimuth_rad), np.rad2deg(image.elevation_rad)
    da = (az[1] - az[0]) / 2 if az.size > 1 else 0.5
    de = (el[1] - el[0]) / 2 if el.size > 1 else 0.5
    db = to_db(image.power[r], image.power.max(), -dynamic_range_db)
    im = ax.imshow(
        db[:, ::-1],  # column 0 is the largest azimuth, drawn at the left edge
        origin="lower",
        aspect="auto",
        cmap=CMAP,
        vmin=-dynamic_range_db,
        vmax=0,
        interpolation="nearest",
        # left edge = largest azimuth: seen from behind the sensor, left is left
        extent=(az[-1] + da, az[0] - da, el[0] - de, el[-1] + de),
    )
    ax.set_xlim(az[-1] + da, az[0] - da)  # marks at the grid's edge do not widen it
    ax.set_ylim(el[0] - de, el[-1] + de)
    ax.set_title(f"{image.range_m[r]:.2f} m", fontsize=10)
    ax.set_xlabel("azimuth (°), left +")
    return im


def make_elaz_figure(
    image: Image,
    *,
    n_slices: int = 3,
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    title: str | None = None,
    truth=None,
    truth_tolerance_m: float | None = None,
):
    """Elevation-azimuth maps at the range slices of the `n_slices` strongest distinct
    echoes inside the grid (see :func:`pick_slices`), seen from behind the sensor
    (azimuth grows to the left), in dB relative to the image's strongest cell.
    Returns the matplotlib Figure.

    truth : optional traced reflectors (as for :func:`make_fan_figure`); those
        within `truth_tolerance_m` (default: three range bins; the pictures give half
        the image's range resolution, :mod:`acousim.imaging.matching`) of a slice's range
        are marked on it (:func:`acousim.viz.truth.elaz_marks`).
    """
    from acousim.viz.truth import elaz_marks, legend_handles

    plt = _plt()
    if image.power.size == 0:
        raise ValueError(f"image {image.method!r} has no range bins to draw")
    picks = sorted(
        pick_slices(image, n_slices, dynamic_range_db=dynamic_range_db),
        key=lambda i: image.range_m[i],
    )
    fig, axes = plt.subplots(
        1,
        len(picks),
        figsize=(3.6 * len(picks) + 1.0, 4.2),
        squeeze=False,
        sharey=True,
        layout="constrained",
    )
    tol = truth_tolerance_m if truth_tolerance_m is not None else 3 * (image.bin_range_m or 0.01)
    spans = (
        (float(image.azimuth_rad.min()), float(image.azimuth_rad.max())),
        (float(image.elevation_rad.min()), float(image.elevation_rad.max())),
    )
    im, drawn = None, set()
    for k, (ax, r) in enumerate(zip(axes[0], picks)):
        im = _elaz_panel(ax, image, r, dynamic_range_db)
        if truth is not None and len(truth):
            marks = elaz_marks(truth, float(image.range_m[r]), tol, *spans, dynamic_range_db)
            drawn |= marks.draw(ax, 40.0, min_separation=4.0)  # degrees
        if k == 0:
            ax.set_ylabel("elevation (°), up +")
    fig.colorbar(im, ax=axes[0].tolist(), shrink=0.9, label=colorbar_label(dynamic_range_db))
    if drawn:
        legend_inside(fig, legend_handles(drawn, dynamic_range_db))
    head = f"{image.method}: strongest distinct echoes, {dynamic_range_db:g} dB dynamic range"
    if truth is not None:
        head += f"; marks: traced echoes within {tol * 100:.0f} cm of the slice's range"
    fitted_title(fig, f"{title}\n{head}" if title else head)
    return fig
