"""Truth images: a label map of the same shape as an acoustic image, per cell the
object and the path order that carry most of the cell's simulated energy.

Each traced path (the direct path left out) puts its energy at the array (its
amplitude squared) where the sensor sees it: at its apparent position
(:attr:`processing.GroundTruth.apparent_position_sensor_m`; a path behind a planar
array at its mirror, as it is heard), spread over its resolution cell by a Gaussian
taper whose full width at half maximum is the cell (range and angle,
:class:`acousim.imaging.matching.Resolution`), cut at one full cell.  The energy of every
(object, order) class is summed per cell; the class with the most labels the cell.
A cell whose summed energy lies more than the dynamic range below the strongest
cell's is labelled -1 (none), as are cells no path reaches.  Paths more than
:data:`NEGLIGIBLE_DB` below that floor (re the strongest path) are left out: a
thousand of them in one cell would be needed to reach it.

This is what a segmentation model trains on: the image's cell (r, e, a) holds the
object ``object_names[object_index[r, e, a]]`` seen through a path of ``order[r, e,
a]`` reflections.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.imaging.matching import image_resolution
from acousim.viz.truth import own_sonar, seen_positions, shown_paths
from processing.base.kernels import optional_kernel

__all__ = ["LabelMap", "NEGLIGIBLE_DB", "label_map", "recording_label_map", "sample_labels"]

_LN16 = 4 * np.log(2)  # exp(-4 ln 2 (x / w)^2): 1/2 at x = w / 2
#: paths this far below the dynamic range's floor (re the strongest path's energy)
#: are left out of a label map (dB)
NEGLIGIBLE_DB = 30.0


@dataclass(frozen=True, eq=False)
class LabelMap:
    """Per cell (R, G) of an image (G directions; (R, E, A) after
    :meth:`reshaped`): `object_index` int32, the index into the ground truth's
    ``object_names`` (-1: none), and `order` int16, the reflections of the paths
    that carry most of the cell's energy (-1: none)."""

    object_index: np.ndarray
    order: np.ndarray

    def reshaped(self, shape: tuple[int, ...]) -> LabelMap:
        """Both maps reshaped (to the image's (R, E, A))."""
        return LabelMap(self.object_index.reshape(shape), self.order.reshape(shape))


def label_map(
    *,
    range_m: np.ndarray,
    directions: np.ndarray,
    positions_m: np.ndarray,
    energy: np.ndarray,
    object_index: np.ndarray,
    order: np.ndarray,
    cell: tuple[float, float],
    dynamic_range_db: float,
) -> LabelMap:
    """The label map of an image grid (see the module docstring).

    range_m : (R,) the image's range bins from the array centre, m.
    directions : (G, 3) the image's unit directions, sensor frame.
    positions_m : (P, 3) where each path shows (its apparent position from the array
        centre, sensor frame, m; mirror those behind a planar array first).
    energy : (P,) each path's energy at the array (amplitude squared).
    object_index, order : (P,) int, each path's object (-1: none) and reflections.
    cell : the image's resolution (full widths): (range m, angle rad)
        (:class:`acousim.imaging.matching.Resolution`'s two numbers).
    dynamic_range_db : cells this far below the strongest cell's energy are -1.

    With numba, the steps of :mod:`acousim.imaging.labels_kernel` run compiled; without
    it their numpy and scipy forms give the same bits, more slowly.
    """
    rng = np.asarray(range_m, float).reshape(-1)
    u = np.asarray(directions, float).reshape(-1, 3)
    R, G = rng.size, len(u)
    pos = np.asarray(positions_m, float).reshape(-1, 3)
    e = np.asarray(energy, float).reshape(-1)
    ok = np.isfinite(e) & (e > 0) & np.all(np.isfinite(pos), axis=1)
    if not (R and G and ok.any()):
        return _none(R, G)
    # paths far below the floor cannot reach it: a thousand of them in one cell would
    # be needed (the strongest path's cell has at least its energy)
    ok &= e >= e[ok].max() * 10 ** (-(dynamic_range_db + NEGLIGIBLE_DB) / 10)
    pos, e = pos[ok], e[ok]
    obj = np.asarray(object_index).reshape(-1)[ok].astype(np.int64)
    odr = np.asarray(order).reshape(-1)[ok].astype(np.int64)
    classes, cls = np.unique(np.column_stack([obj, odr]), axis=0, return_inverse=True)
    cls = cls.reshape(-1)
    k_range, k_angle = _factors(rng, u, pos, e, *cell)
    total, top = _total_and_top(k_range, k_angle, cls, len(classes))
    floor_ratio = 10 ** (-dynamic_range_db / 10)
    kernel = optional_kernel("acousim.imaging.labels_kernel", "pick_labels")
    if kernel is not None:  # one pass, every cell written
        out = LabelMap(np.empty((R, G), np.int32), np.empty((R, G), np.int16))
        kernel(
            total,
            top,
            classes[:, 0].copy(),
            classes[:, 1].copy(),
            floor_ratio,
            out.object_index,
            out.order,
        )
        return out
    total, top = total.reshape(-1), top.reshape(-1)
    if not total.any():
        return _none(R, G)
    shown = (top >= 0) & (total >= total.max() * floor_ratio)
    out = _none(R * G, 1)
    out.object_index[shown, 0] = classes[top[shown], 0]
    out.order[shown, 0] = classes[top[shown], 1]
    return out.reshaped((R, G))


def _none(R: int, G: int) -> LabelMap:
    """A label map (R, G) of no labels (-1)."""
    return LabelMap(np.full((R, G), -1, np.int32), np.full((R, G), -1, np.int16))


def _total_and_top(k_range, k_angle, cls: np.ndarray, n_classes: int):
    """Per cell (R, G), the energy of all classes summed in class order and the
    strongest class (-1: none), from the compiled kernel or the sparse product."""
    R, G = k_range.shape[1], k_angle.shape[1]
    kernel = optional_kernel("acousim.imaging.labels_kernel", "cell_classes")
    if kernel is not None:
        by_bin = k_range.tocsc()  # per bin, its paths in order
        by_bin.sort_indices()
        total, top = np.empty((R, G)), np.empty((R, G), np.int32)  # every cell written
        kernel(
            by_bin.indptr, by_bin.indices, by_bin.data, k_angle.indptr, k_angle.indices,
            k_angle.data, cls.astype(np.int64), n_classes, total, top,
        )  # fmt: skip
        return total, top
    cells, k, part = _class_energy(k_range, k_angle, cls, n_classes)
    total = np.bincount(cells, weights=part, minlength=R * G)  # classes summed in order
    return total.reshape(R, G), _strongest_class(cells, k, part, R * G).reshape(R, G)


def _class_energy(k_range, k_angle, cls: np.ndarray, n_classes: int):
    """Every class's energy on the cells its paths reach, from one sparse product:
    the range kernels (P, R) transposed times the angle kernels (P, G) with each
    path's row moved to its class's block of columns (P, C G).  Returns, per nonzero
    (N,), the flat cell r G + g, the class and the energy, ordered by class (so that
    summing them in order adds the classes in order)."""
    from scipy import sparse

    G = k_angle.shape[1]
    k_angle = k_angle.tocsr()
    shifted = sparse.csr_matrix(
        (
            k_angle.data,
            k_angle.indices + np.repeat(cls * G, np.diff(k_angle.indptr)),
            k_angle.indptr,
        ),
        shape=(k_angle.shape[0], n_classes * G),
    )
    part = sparse.csc_matrix(k_range.T @ shifted)  # (R, C G), by column: class-major
    column = np.repeat(np.arange(n_classes * G), np.diff(part.indptr))
    k, g = np.divmod(column, G)
    return part.indices.astype(np.int64) * G + g, k, part.data


def _strongest_class(cells: np.ndarray, k: np.ndarray, part: np.ndarray, n_cells: int):
    """Per cell (n_cells,), the class with the most energy there (the first of equals;
    -1 where none has any), from the nonzeros of :func:`_class_energy`."""
    best = np.zeros(n_cells)
    np.maximum.at(best, cells, part)
    win = (part > 0) & (part == best[cells])
    top = np.full(n_cells, np.iinfo(np.int64).max)
    np.minimum.at(top, cells[win], k[win])
    top[top == np.iinfo(np.int64).max] = -1
    return top


def _factors(rng, u, pos, e, range_cell_m, angle_cell_rad, chunk: int = 256):
    """The separable kernels of P paths as sparse matrices: range (P, R), each path's
    energy times its taper over the bins within one cell of its range, and angle
    (P, G), its taper over the directions within one cell of its own."""
    from scipy import sparse

    r = np.linalg.norm(pos, axis=1)
    d = pos / np.maximum(r, 1e-12)[:, None]
    wr, wa = max(float(range_cell_m), 1e-9), max(float(angle_cell_rad), 1e-9)
    lo = np.searchsorted(rng, r - wr)
    n = np.searchsorted(rng, r + wr, side="right") - lo
    rows = np.repeat(np.arange(len(r)), n)
    cols = lo[rows] + np.arange(rows.size) - np.repeat(np.cumsum(n) - n, n)
    vals = e[rows] * np.exp(-_LN16 * ((rng[cols] - r[rows]) / wr) ** 2)
    # the entries come row by row, each row's columns in order: CSR as they are
    indptr = np.r_[0, np.cumsum(n)]
    k_range = sparse.csr_matrix((vals, cols, indptr), shape=(len(r), rng.size))
    cos_cut = np.cos(min(wa, np.pi))
    near = _near_directions(cos_cut, min(chunk, len(d)) * len(u))
    parts = []
    for start in range(0, len(d), chunk):  # (chunk, G) at a time
        g, dots, count = near(d[start : start + chunk] @ u.T)
        ang = np.arccos(np.clip(dots, -1.0, 1.0))
        parts.append((np.exp(-_LN16 * (ang / wa) ** 2), g, count))
    w, g, count = (np.concatenate(x) for x in zip(*parts))
    k_angle = sparse.csr_matrix((w, g, np.r_[0, np.cumsum(count)]), shape=(len(d), len(u)))
    return k_range, k_angle


def _near_directions(cos_cut: float, size: int):
    """A function of dots (n, G) giving the columns (N,) and values (N,) of the entries
    at or above `cos_cut`, row by row, and each row's count (n,): the compiled kernel's
    (one pass; buffers of `size` >= n G reused) or numpy's."""
    kernel = optional_kernel("acousim.imaging.labels_kernel", "near_directions")
    if kernel is None:

        def near(dots):
            i, g = np.nonzero(dots >= cos_cut)  # row by row, each row's columns in order
            return g, dots[i, g], np.bincount(i, minlength=len(dots))

        return near
    cols, values = np.empty(size, np.int64), np.empty(size)

    def compiled(dots):
        counts = np.empty(len(dots), np.int64)
        m = kernel(dots, cos_cut, cols, values, counts)
        return cols[:m].copy(), values[:m].copy(), counts

    return compiled


def recording_label_map(rec, image, resolution, dynamic_range_db: float, range_m=None):
    """The :class:`LabelMap` (R, E, A) of `image` (a :class:`processing.Image` of
    the :class:`processing.Recording` `rec`) on its range bins (or `range_m` (R,),
    a regular axis it is written on), with the image's `resolution`
    (:func:`acousim.imaging.matching.image_resolution`); None without a ground truth."""
    t = rec.truth
    if t is None:
        return None
    rng = np.asarray(image.range_m if range_m is None else range_m, float)
    el, az = np.meshgrid(image.elevation_rad, image.azimuth_rad, indexing="ij")
    u = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1)
    pos = seen_positions(t, rec.array.positions_m.mean(axis=0))
    pos[:, 0] = np.abs(pos[:, 0])  # behind a planar array: heard at its mirror
    echo = shown_paths(t, own_sonar(rec))
    obj = t.object_index if t.object_index is not None else np.full(len(t), -1)
    labels = label_map(
        range_m=rng,
        directions=u.reshape(-1, 3),
        positions_m=pos[echo],
        energy=np.square(t.amplitude[echo]),
        object_index=obj[echo],
        order=t.order[echo],
        cell=(resolution.range_m, resolution.angle_rad),
        dynamic_range_db=dynamic_range_db,
    )
    return labels.reshaped((rng.size, *el.shape))


#: the per-path truth a dataset sample stores beside position, amplitude and order:
#: (key, GroundTruth field, dtype, units, dimensions)
SAMPLE_FIELDS = (
    ("labels/delay_s", "delay_s", np.float32, "s", "path"),
    ("labels/arrival_sensor", "arrival_sensor", np.float32, "1", "path,xyz"),
    (
        "labels/apparent_position_sensor_m",
        "apparent_position_sensor_m",
        np.float32,
        "m",
        "path,xyz",
    ),
    ("labels/object_index", "object_index", np.int16, "1", "path"),
)


def sample_labels(rec, images, range_m, window_samples: int, dynamic_range_db: float) -> dict:
    """A dataset sample's truth beyond position, amplitude and order: the per-path
    fields of :data:`SAMPLE_FIELDS` (those the recording has) and each image's label
    maps ``label_map/<method>/object`` (int16) and ``label_map/<method>/order``
    (int8), (R, E, A) on the sample's range axis `range_m` (R,).  `images`:
    {method: :class:`processing.Image`}."""
    t = rec.truth
    out: dict[str, np.ndarray] = {}
    if t is None:
        return out
    for key, name, dtype, _units, _dims in SAMPLE_FIELDS:
        if getattr(t, name) is not None:
            out[key] = getattr(t, name).astype(dtype)
    for m, img in images.items():
        res = image_resolution(rec, img, window_samples)
        lab = recording_label_map(rec, img, res, dynamic_range_db, range_m=range_m)
        out[f"label_map/{m}/object"] = lab.object_index.astype(np.int16)
        out[f"label_map/{m}/order"] = lab.order.astype(np.int8)
    return out
