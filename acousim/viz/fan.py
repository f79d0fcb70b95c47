"""Fan images (azimuth x range, the top view of the paper's Figs. 13-14) and
elevation-azimuth maps, with matplotlib (Agg).  Files are written atomically."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from processing import Image, to_db


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.part{path.suffix}")
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    os.replace(tmp, path)
    return path


def full_range_fan(
    image: Image, max_range_m: float | None = None, elevation_limit_rad: float = np.deg2rad(30.0)
) -> tuple[np.ndarray, np.ndarray]:
    """Top view on a regular range axis: (range_m (R',), power (R', A)).

    Each cell is the maximum over the elevations within ``elevation_limit_rad`` of the
    horizontal plane (near the poles every azimuth is the same direction, which would
    smear the view); range bins the energy gate dropped are 0.
    """
    step = image.bin_range_m or 0.01
    top = (
        max_range_m
        if max_range_m is not None
        else (float(image.range_m.max()) if image.range_m.size else step)
    )
    axis = np.arange(0.0, top + step / 2, step)
    fan = np.zeros((axis.size, image.azimuth_rad.size))
    if image.range_m.size:
        idx = np.rint(image.range_m / step).astype(int)
        ok = (idx >= 0) & (idx < axis.size)
        band = np.abs(image.elevation_rad) <= elevation_limit_rad
        if not band.any():
            band = np.abs(image.elevation_rad) == np.abs(image.elevation_rad).min()
        fan[idx[ok]] = np.maximum(fan[idx[ok]], image.power[ok][:, band].max(axis=1))
    return axis, fan


def fan_figure(
    images: Mapping[str, Image],
    path: str | Path,
    *,
    max_range_m: float | None = None,
    dynamic_range_db: float = 25.0,
    title: str | None = None,
    truth=None,
) -> Path:
    """One fan panel per method, side by side (x forward, y to the left).

    `truth` : optional (N, 3) positions (sensor frame) drawn as white circles.
    """
    plt = _plt()
    n = len(images)
    cols = n if n <= 4 else int(np.ceil(n / 2))
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.8 * cols, 2.5 * rows + 0.6), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    if max_range_m is None:
        max_range_m = (
            max((float(im.range_m.max()) for im in images.values() if im.range_m.size), default=1.0)
            * 1.05
        )
    for ax, (method, img) in zip(axes.ravel(), images.items()):
        draw_fan(ax, img, max_range_m, dynamic_range_db)
        if truth is not None and len(truth):
            t = np.asarray(truth)
            ax.scatter(-t[:, 1], t[:, 0], s=90, facecolors="none", edgecolors="cyan", lw=0.6)
        ax.set_title(method)
    if title:
        fig.suptitle(title)
    out = _save(fig, Path(path))
    plt.close(fig)
    return out


def draw_fan(
    ax,
    image: Image,
    max_range_m: float,
    dynamic_range_db: float = 25.0,
    pixels: int = 800,
) -> None:
    """Draw the top view of an image on a matplotlib axis (x forward up, y left).

    The polar cells are rasterised onto `pixels` columns (nearest cell per pixel)
    after the range bins are max-pooled to the raster's resolution, so that no echo
    thinner than a pixel disappears; far faster than a mesh of every cell.
    """
    rng, fan = full_range_fan(image, max_range_m)
    if rng.size > pixels // 2:  # about `pixels` / 2 pixels cover the range
        k = -(-rng.size // (pixels // 2))
        pad = -rng.size % k
        fan = np.pad(fan, ((0, pad), (0, 0))).reshape(-1, k, fan.shape[1]).max(axis=1)
        rng = rng[0] + (rng[1] - rng[0]) * (k * np.arange(fan.shape[0]) + (k - 1) / 2)
    db = to_db(fan, floor_db=-dynamic_range_db)
    r_edges, a_edges = _edges(rng), _edges(image.azimuth_rad)
    A, Rg = np.meshgrid(a_edges, r_edges)
    X, Y = -Rg * np.sin(A), Rg * np.cos(A)  # horizontal: y to the left; vertical: x
    extent = (X.min(), X.max(), Y.min(), Y.max())
    height = max(int(round(pixels * (extent[3] - extent[2]) / (extent[1] - extent[0]))), 1)
    PX, PY = np.meshgrid(_centres(extent[0], extent[1], pixels), _centres(*extent[2:], height))
    i = np.searchsorted(r_edges, np.hypot(PX, PY)) - 1
    j = np.searchsorted(a_edges, np.arctan2(-PX, PY)) - 1
    inside = (i >= 0) & (i < db.shape[0]) & (j >= 0) & (j < db.shape[1])
    raster = np.full(PX.shape, np.nan)
    raster[inside] = db[i[inside], j[inside]]
    ax.imshow(
        raster,
        origin="lower",
        extent=extent,
        cmap="inferno",
        vmin=-dynamic_range_db,
        vmax=0,
        interpolation="nearest",
    )
    ax.set_aspect("equal")
    ax.set_xlabel("y (m), left ←")
    ax.set_ylabel("x forward (m)")
    ax.set_facecolor("black")


def _centres(lo: float, hi: float, n: int) -> np.ndarray:
    """Centres (n,) of n equal cells covering [lo, hi]."""
    return lo + (np.arange(n) + 0.5) * (hi - lo) / n


def _edges(x: np.ndarray) -> np.ndarray:
    """Cell edges around centres x (n,): (n + 1,)."""
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = (x[1:] + x[:-1]) / 2
    return np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])


def elaz_figure(
    image: Image, path: str | Path, *, n_slices: int = 3, dynamic_range_db: float = 40.0
) -> Path:
    """Elevation-azimuth maps at the `n_slices` strongest range bins."""
    plt = _plt()
    if image.power.size == 0:
        raise ValueError(f"image {image.method!r} has no range bins to draw")
    strength = image.power.reshape(image.power.shape[0], -1).max(axis=1)
    order = np.argsort(strength)[::-1]
    picks, used = [], []
    for r in order:  # strongest bins, at least two bins apart
        if all(abs(r - u) > 2 for u in used):
            picks.append(r)
            used.append(r)
        if len(picks) == n_slices:
            break
    fig, axes = plt.subplots(1, len(picks), figsize=(4 * len(picks), 3.4), squeeze=False)
    ref = image.power.max()
    for ax, r in zip(axes[0], sorted(picks)):
        db = to_db(image.power[r], ref, -dynamic_range_db)
        ax.imshow(
            db,
            origin="lower",
            aspect="auto",
            cmap="inferno",
            vmin=-dynamic_range_db,
            vmax=0,
            extent=np.rad2deg(
                [
                    image.azimuth_rad[0],
                    image.azimuth_rad[-1],
                    image.elevation_rad[0],
                    image.elevation_rad[-1],
                ]
            ),
        )
        ax.set_title(f"{image.method}, {image.range_m[r]:.2f} m")
        ax.set_xlabel("azimuth (°)")
        ax.set_ylabel("elevation (°)")
    out = _save(fig, Path(path))
    plt.close(fig)
    return out
