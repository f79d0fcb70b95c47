"""Acoustic images and their peaks as files any tool can read.

Why HDF5 with dimension scales (and not NetCDF through xarray/h5netcdf): the
recordings are already HDF5 and h5py is already a dependency, so nothing new is
installed; dimension scales attach the axes (with units) to every image, which
h5py, MATLAB's ``h5read``/``h5info`` and HDFView show, and xarray opens each group
as a netCDF-4 dataset through h5netcdf (tested). The images are compressed with
gzip (shuffle and deflate at level 1: every HDF5 tool reads it; the deflate streams
made by ISA-L when the ``isal`` package is installed, :func:`deflate`;
``compression="lzf"``, for h5py, h5netcdf and xarray alone).

Layout of ``images.h5`` (one group per imaged recording; see docs/export.md)::

    /                               attrs: format = "acousim-images", version = 1
    /recording_000030/              attrs: index (in the recording file), scene,
                                    provenance (simulated/real/emulated), time_s,
                                    position_m, yaw_deg, pitch_deg, roll_deg
        range_m        (R,)  float64  dimension scale, units "m"
        elevation_deg  (E,)  float64  dimension scale, units "degree"
        azimuth_deg    (A,)  float64  dimension scale, units "degree"
        <method>       (R, E, A) float32  level in dB relative to the strongest cell
                       of that image (0 dB), in steps of 1/128 dB; NaN: range bin
                       removed by the energy gate (no data).  attrs: units "dB",
                       method, frequency_hz, reference_power (linear power of 0 dB),
                       resolution_db.
        <method>_object (R, E, A) int16  truth label (simulations): per cell the
                       object (index into object_names) carrying most of its
                       simulated energy; -1 none or below the dynamic range
        <method>_order  (R, E, A) int8   the same cell's path order (reflections)
        object_names   (O,) UTF-8 strings: "<mesh>/<material>", "point <i>"
        peaks/<method>/<column>  (P,) the image's peaks, one dataset per column of
                       peaks.csv but recording, method and provenance

Peaks CSV columns: see :data:`PEAK_COLUMNS`.
"""

from __future__ import annotations

import csv
import io
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

import processing as P
from acousim.imaging.labels import recording_label_map
from acousim.imaging.matching import image_resolution
from acousim.imaging.run import PEAK_THRESHOLD_DB, peak_table
from acousim.viz.fan import DYNAMIC_RANGE_DB
from processing.base.atomic import atomic_path, write_text

if TYPE_CHECKING:
    from acousim.imaging.labels import LabelMap
    from acousim.imaging.matching import Resolution

__all__ = [
    "FORMAT",
    "Given",
    "Stored",
    "VERSION",
    "PEAK_COLUMNS",
    "image_data_steps",
    "label_maps",
    "label_maps_ahead",
    "peaks_csv_text",
    "write_image_data",
    "write_peaks_csv",
]

QUANTUM_PER_DB = 128  # levels are stored as multiples of 1/128 dB
FORMAT = "acousim-images"
VERSION = 1

#: the peaks CSV's columns: :class:`processing.PeakRow`'s fields (declared there, once)
PEAK_COLUMNS = P.PEAK_COLUMNS


def _group_name(index: int, width: int) -> str:
    return f"recording_{index:0{width}d}"


def regular_range_axis(images: Sequence[P.Image]) -> np.ndarray:
    """One regular range axis (R',) covering the kept bins of all `images` (same
    recording, so the same bins): from the nearest to the farthest kept bin, in steps
    of the STFT bin; bins in between that the energy gate removed are on it too."""
    kept = [im for im in images if im.range_m.size]
    if not kept:
        return np.empty(0)
    lo = min(float(im.range_m.min()) for im in kept)
    hi = max(float(im.range_m.max()) for im in kept)
    step = kept[0].bin_range_m or (
        float(np.min(np.diff(kept[0].range_m))) if kept[0].range_m.size > 1 else 1.0
    )
    return lo + step * np.arange(int(np.rint((hi - lo) / step)) + 1)


#: images.h5's gzip level (1-9) when ``compression="gzip"`` is asked: the level its
#: datasets' filter records, and zlib's when ISA-L is not installed (:func:`deflate`)
GZIP_LEVEL = 1
#: range bins per chunk of an image (each chunk: this many whole elevation-azimuth
#: planes); the gated bins' chunks are never written (read back as NaN, the fill value)
CHUNK_BINS = 4
#: range bins per chunk of a label map (gzip: every chunk stored, each of whole planes)
LABEL_CHUNK_BINS = 16
#: ISA-L's deflate level (0-3) when the ``isal`` package is there (:func:`deflate`)
ISAL_LEVEL = 1


@dataclass(frozen=True)
class Stored:
    """What images.h5 stores besides the images, and how (:func:`write_image_data`'s
    keywords of the same names): the label maps' `dynamic_range_db` (dB), the peaks
    at least `peak_threshold_db` (dB re the strongest cell), the `compression`."""

    compression: str | None = "gzip"
    dynamic_range_db: float = DYNAMIC_RANGE_DB
    peak_threshold_db: float = PEAK_THRESHOLD_DB


@dataclass(frozen=True)
class Given:
    """What a caller of :func:`write_image_data` may hand it besides the images (each
    None: made there, or no progress reported).

    tables : the images' peak tables (:func:`peak_tables`, with the same threshold),
        taken one recording at a time as its group is written (an iterator may make
        each when asked).
    labels : each recording's label maps (:func:`label_maps`, with the same dynamic
        range), taken one recording at a time as its group is written (an iterator
        fed by another process may still be making the later ones).
    progress : called ``(done, total)`` after each recording's group is written.
    """

    tables: Iterable[Mapping[str, P.PeakTable]] | None = None
    labels: Iterable[Mapping[Resolution, LabelMap]] | None = None
    progress: Callable[[int, int], None] | None = None


def write_image_data(
    path: str | Path,
    recordings: Sequence[P.Recording],
    images: Sequence[Mapping[str, P.Image]],
    indices: Sequence[int] | None = None,
    *,
    compression: str | None = "gzip",
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
    peak_threshold_db: float = PEAK_THRESHOLD_DB,
    given: Given = Given(),
) -> Path:
    """Write every image of every recording to one HDF5 file (atomically), with the
    truth labels of each image of a simulated recording (:mod:`acousim.imaging.labels`).

    recordings, images : as from :func:`acousim.imaging.run.image_recordings`.
    indices : each recording's index in its file (default 0, 1, ...).
    dynamic_range_db : cells of the label maps this far below the strongest cell's
        simulated energy are labelled -1 (none).
    peak_threshold_db : the peaks stored (``peaks/<method>``, as ``peaks.csv``).
    compression : HDF5's filter, with shuffle: "gzip" (default, :data:`GZIP_LEVEL`: read by
        every HDF5 tool, MATLAB and HDFView included), "lzf" (h5py's own: 1.3x faster
        to write than gzip at level 1, the file a quarter larger, read by h5py,
        h5netcdf and xarray, not by MATLAB without its plugin) or None.
    given : the peak tables and label maps made already, a progress callback (:class:`Given`).
    """
    path = Path(path)
    stored = Stored(compression, dynamic_range_db, peak_threshold_db)
    with atomic_path(path) as tmp:
        steps = image_data_steps(tmp, recordings, images, indices, stored=stored, given=given)
        for done, total in steps:
            if given.progress is not None:
                given.progress(done, total)
    return path


def image_data_steps(
    path: str | Path,
    recordings: Sequence[P.Recording],
    images: Sequence[Mapping[str, P.Image]],
    indices: Sequence[int] | None = None,
    *,
    stored: Stored = Stored(),
    given: Given = Given(),
) -> Iterator[tuple[int, int]]:
    """:func:`write_image_data`'s work (its keywords in `stored`), written straight
    to `path` (not atomically: for a caller that renames it into place itself, or
    another process writing to a caller's temporary file): yields ``(done, total)``
    after each recording's group (`given.progress` is not called)."""
    import h5py

    compression, dynamic_range_db = stored.compression, stored.dynamic_range_db
    peak_threshold_db = stored.peak_threshold_db
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    tables = given.tables
    if tables is None:
        tables = peak_tables(recordings, images, indices, peak_threshold_db)
    if given.labels is not None:
        labels = iter(given.labels)
    else:
        labels = label_maps_ahead(recordings, images, dynamic_range_db)
    width = max(6, len(str(max(indices, default=0))))
    with h5py.File(path, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["version"] = VERSION
        f.attrs["description"] = (
            "acoustic images: level in dB re the strongest cell of each image, "
            "dimensions (range_m, elevation_deg, azimuth_deg); NaN = no data"
        )
        for done, (idx, rec, imgs, table) in enumerate(zip(indices, recordings, images, tables)):
            g = f.create_group(_group_name(idx, width))
            g.attrs["index"] = idx
            # label maps by resolution (methods of one frequency share one)
            made = {r: (m, {}) for r, m in next(labels).items()}
            _write_recording(g, rec, imgs, table, (dynamic_range_db, compression, made))
            yield done + 1, len(recordings)


def label_maps_ahead(
    recordings: Sequence[P.Recording],
    images: Sequence[Mapping[str, P.Image]],
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
) -> Iterator[Mapping[Resolution, LabelMap]]:
    """Each recording's label maps (:func:`label_maps`), in order, the next one made
    in a thread while the caller works on the last one handed out (numpy, scipy, the
    compiled kernel and zlib free the GIL)."""
    return _one_ahead(label_maps(recordings, images, dynamic_range_db))


def _one_ahead(items: Iterator) -> Iterator:
    """The items of `items`, the next one made in a thread while the caller works
    on the last one handed out."""
    from concurrent.futures import ThreadPoolExecutor

    end = object()
    with ThreadPoolExecutor(1) as pool:
        coming = pool.submit(next, items, end)
        while (item := coming.result()) is not end:
            coming = pool.submit(next, items, end)
            yield item


def _write_recording(g, rec: P.Recording, imgs, table, labels: tuple) -> None:
    """One recording's group `g`: its provenance, axes, images, label maps (`labels`:
    as :func:`_write_labels` takes them), peaks and object names."""
    import h5py

    _write_provenance(g, rec.provenance)
    first = next(iter(imgs.values()))
    axis = regular_range_axis(list(imgs.values()))
    scales = {
        "range_m": (axis, "m"),
        "elevation_deg": (np.rad2deg(first.elevation_rad), "degree"),
        "azimuth_deg": (np.rad2deg(first.azimuth_rad), "degree"),
    }
    for name, (values, units) in scales.items():
        d = g.create_dataset(name, data=values)
        d.attrs["units"] = units
        d.make_scale(name)
    for method, img in imgs.items():
        _write_image(g, method, img, axis, list(scales), labels[1])
        _write_labels(g, rec, (method, img), axis, list(scales), *labels)
        peaks = g.require_group("peaks").create_group(method)
        _write_peaks(peaks, table[method])
    if rec.truth is not None and rec.truth.object_index is not None:
        names = list(rec.truth.object_names)
        g.create_dataset("object_names", data=names, dtype=h5py.string_dtype("utf-8"))


#: the peak columns images.h5 stores (per image; the recording and method are its
#: group's, the provenance its recording's)
_H5_PEAK_COLUMNS = tuple(c for c in PEAK_COLUMNS if c not in ("recording", "method", "provenance"))


def peak_tables(
    recordings: Sequence[P.Recording],
    images: Sequence[Mapping[str, P.Image]],
    indices: Sequence[int] | None = None,
    threshold_db: float = PEAK_THRESHOLD_DB,
) -> list[dict[str, P.PeakTable]]:
    """Each image's peaks within `threshold_db` (dB) as rows (:func:`acousim.peak_table`,
    matched to the traced paths), per recording {method: table}: made once for
    ``images.h5`` and ``peaks.csv`` alike."""
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    return [
        {m: peak_table(rec, img, threshold_db=threshold_db, index=idx) for m, img in imgs.items()}
        for idx, rec, imgs in zip(indices, recordings, images)
    ]


def _write_peaks(g, rows: P.PeakTable) -> None:
    """An image's peak rows (those of ``peaks.csv``, strongest first, with their truth)
    as one dataset (P,) per column: numbers float64 (NaN: none), integers and
    flags int32 (-1: none), text UTF-8 ("": none)."""
    import h5py

    for name in _H5_PEAK_COLUMNS:
        values = [getattr(row, name) for row in rows]
        if name in _TEXT_COLUMNS:
            g.create_dataset(name, data=values, dtype=h5py.string_dtype("utf-8"))
        elif name in _INT_COLUMNS:
            ints = [-1 if v is None or v == "" else int(v) for v in values]
            g.create_dataset(name, data=ints, dtype=np.int32)
        else:
            g.create_dataset(name, data=[np.nan if v is None else v for v in values], dtype=float)


_TEXT_COLUMNS = ("truth_kind", "truth_object", "truth_emitter", "truth_note")
_INT_COLUMNS = ("on_grid_edge", "truth_order", "truth_behind")


def label_maps(
    recordings: Sequence[P.Recording],
    images: Sequence[Mapping[str, P.Image]],
    dynamic_range_db: float = DYNAMIC_RANGE_DB,
) -> Iterator[dict[Resolution, LabelMap]]:
    """Each recording's label maps as :func:`write_image_data` writes them, in order:
    {resolution: :class:`acousim.imaging.labels.LabelMap` (R, E, A) on the regular
    range axis}, one per resolution of its images (methods of one frequency share
    one); {} for a recording without a ground truth or range bins.  Made one
    recording at a time, when asked."""

    for rec, imgs in zip(recordings, images):
        axis = regular_range_axis(list(imgs.values()))
        made: dict = {}
        if rec.truth is not None and axis.size:
            for img in imgs.values():
                res = image_resolution(rec, img, P.ProcessingSettings.window)
                if res not in made:
                    made[res] = recording_label_map(rec, img, res, dynamic_range_db, range_m=axis)
        yield made


def _write_labels(g, rec, image, axis, scales: list, dynamic_range_db, compression, made):
    """The image's truth labels (:mod:`acousim.imaging.labels`) beside it: ``<method>_object``
    (int16 index into the group's ``object_names``, -1 none) and ``<method>_order``
    (int8 reflections, -1 none), of the image's shape; `made` holds those made for
    the recording's other images, by resolution, with their compressed chunks (with
    gzip: made once, written as they are for every method of that resolution)."""

    method, img = image
    if rec.truth is None or not axis.size:
        return
    res = image_resolution(rec, img, P.ProcessingSettings.window)
    if res not in made:
        made[res] = (recording_label_map(rec, img, res, dynamic_range_db, range_m=axis), {})
    labels, packed = made[res]
    for suffix, data, dtype, what in (
        ("object", labels.object_index, np.int16, "index into object_names"),
        ("order", labels.order, np.int8, "reflections"),
    ):
        name = f"{method}_{suffix}"
        values = data.astype(dtype)
        if compression == "gzip" and values.size and sys.byteorder == "little":
            chunks = (min(LABEL_CHUNK_BINS, values.shape[0]), *values.shape[1:])
            d = g.create_dataset(
                name, shape=values.shape, dtype=dtype, chunks=chunks, compression="gzip",
                compression_opts=GZIP_LEVEL, shuffle=True,
            )  # fmt: skip
            if suffix not in packed:  # the same map as another method's: its chunks
                packed[suffix] = _packed_chunks(values, chunks[0])
            for offset, raw in packed[suffix]:
                d.id.write_direct_chunk(offset, raw, 0)
        else:
            d = g.create_dataset(
                name, data=values, chunks=True, compression=compression, shuffle=bool(compression)
            )
        d.attrs["long_name"] = (
            f"{method}: per cell, the {what} of the paths carrying most of its simulated "
            "energy (-1: none, or below the dynamic range)"
        )
        d.attrs["dynamic_range_db"] = float(dynamic_range_db)
        for dim, scale in enumerate(scales):
            d.dims[dim].label = scale
            d.dims[dim].attach_scale(g[scale])


def _packed_chunks(values: np.ndarray, bins: int) -> list[tuple[tuple[int, ...], bytes]]:
    """`values` (R, E, A) cut into chunks of `bins` whole range bins, each as HDF5's
    shuffle and gzip filters store it (:func:`_shuffle_deflate`; the last chunk's rows
    past R hold zeros, never read): (chunk offset, bytes) in order, compressed in
    :data:`GZIP_THREADS` threads."""

    def packed(start: int) -> bytes:
        block = np.zeros((bins, *values.shape[1:]), values.dtype)
        part = values[start : start + bins]
        block[: len(part)] = part
        return _shuffle_deflate(block)

    starts = list(range(0, values.shape[0], bins))
    return [((s, 0, 0), raw) for s, raw in zip(starts, _in_threads(packed, starts))]


def _write_provenance(g, prov) -> None:
    """A recording's scene, provenance kind and pose (degrees) as the group's attributes."""
    g.attrs["scene"] = prov.scene or ""
    g.attrs["provenance"] = prov.kind  # simulated, real or emulated
    if prov.pose is not None:
        g.attrs["time_s"] = prov.pose.time_s
        g.attrs["position_m"] = np.asarray(prov.pose.position_m, float)
        for k in ("yaw", "pitch", "roll"):
            g.attrs[f"{k}_deg"] = float(np.rad2deg(getattr(prov.pose, f"{k}_rad")))


def _write_image(g, method: str, img: P.Image, axis: np.ndarray, scales: list, compression):
    """One image's level (dB, quantised) on the regular range `axis` (m), its
    dimensions attached to the group's `scales`: the kept bins only are written, in
    runs of consecutive bins (the others read back as the fill value, NaN)."""
    shape = (axis.size, img.elevation_rad.size, img.azimuth_rad.size)
    chunked = bool(compression) and bool(np.prod(shape))
    d = g.create_dataset(
        method,
        shape=shape,
        dtype=np.float32,
        chunks=(min(CHUNK_BINS, shape[0]), *shape[1:]) if chunked else None,
        compression=compression if chunked else None,
        compression_opts=GZIP_LEVEL if compression == "gzip" and chunked else None,
        shuffle=chunked,
        fillvalue=np.float32(np.nan),
    )
    if img.range_m.size:
        k = np.rint((img.range_m - axis[0]) / (axis[1] - axis[0] if axis.size > 1 else 1))
        k = k.astype(int)
        # multiples of 1/128 dB (error <= 0.004 dB): the low mantissa bits are
        # zero and the shuffled, compressed file about half the size
        level = P.to_db(img.power, floor_db=-300.0)
        level *= QUANTUM_PER_DB
        np.round(level, out=level)
        level /= QUANTUM_PER_DB
        level = level.astype(np.float32)
        if compression == "gzip" and chunked and sys.byteorder == "little":
            _write_gzip_chunks(d, k, level)
        else:
            cut = np.flatnonzero(np.diff(k) != 1) + 1
            for a, b in zip(np.r_[0, cut], np.r_[cut, k.size]):
                d[k[a] : k[b - 1] + 1] = level[a:b]
    d.attrs["units"] = "dB"
    d.attrs["long_name"] = f"{method} image level re its strongest cell"
    d.attrs["method"] = method
    d.attrs["frequency_hz"] = float(img.frequency_hz)
    d.attrs["reference_power"] = float(img.power.max()) if img.power.size else 0.0
    d.attrs["no_data"] = "NaN: range bin removed by the energy gate"
    d.attrs["resolution_db"] = 1.0 / QUANTUM_PER_DB
    for dim, name in enumerate(scales):
        d.dims[dim].label = name
        d.dims[dim].attach_scale(g[name])


#: threads compressing an image's chunks (zlib frees the GIL): the second core's
#: share once the command's pictures are drawn
GZIP_THREADS = 2


def _write_gzip_chunks(d, k: np.ndarray, level: np.ndarray) -> None:
    """Write `level` (K, E, A) float32 to the bins `k` (K,) of `d` (R, E, A), chunked
    by whole range bins with shuffle and gzip: each chunk that holds a kept bin made
    here as HDF5's filters store it (:func:`_shuffle_deflate`), compressed in
    :data:`GZIP_THREADS` threads and written as it is; the bins not kept hold NaN
    (the fill value), the chunks without a kept bin are not stored (read back as
    NaN).  The values read back are those of writing `level` by slices."""

    bins = d.chunks[0]

    def packed(c: int) -> bytes:
        block = np.full(d.chunks, np.nan, np.float32)  # the edge chunk's rows too
        here = (k >= c * bins) & (k < (c + 1) * bins)
        block[k[here] - c * bins] = level[here]
        return _shuffle_deflate(block)

    chunks = list(np.unique(k // bins))
    for c, raw in zip(chunks, _in_threads(packed, chunks)):
        d.id.write_direct_chunk((int(c) * bins, 0, 0), raw, 0)


def _in_threads(work: Callable, items: list) -> list:
    """``[work(x) for x in items]``, the items split into :data:`GZIP_THREADS` runs
    made in as many threads (one task each: a task per chunk costs more in the
    pool's bookkeeping than compressing it)."""
    from concurrent.futures import ThreadPoolExecutor

    n = max(1, min(GZIP_THREADS, len(items)))
    cut = np.linspace(0, len(items), n + 1).astype(int)
    runs = [items[a:b] for a, b in zip(cut[:-1], cut[1:])]
    with ThreadPoolExecutor(n) as pool:
        return [out for run in pool.map(lambda r: [work(x) for x in r], runs) for out in run]


def _shuffle_deflate(block: np.ndarray) -> bytes:
    """A chunk `block` (little-endian numbers of 1, 2, 4 or 8 bytes) as HDF5's shuffle
    and gzip (deflate) filters store it: the bytes of its elements grouped by
    significance (the first bytes of all, then the second bytes, ...), then one zlib
    stream (:func:`deflate`).  `block` is overwritten (a scratch copy)."""
    size = block.dtype.itemsize
    if size == 1:
        return deflate(block.tobytes())
    word = block.reshape(-1).view(f"u{size}")  # little-endian: byte j = bits 8j..8j+7
    shuffled = np.empty((size, word.size), np.uint8)
    for j in range(size):
        np.copyto(shuffled[j], word, casting="unsafe")  # the low byte (mod 256)
        word >>= 8  # (faster than a strided byte transpose)
    return deflate(shuffled)


def deflate(data) -> bytes:
    """`data` (bytes or a contiguous array) as one zlib stream, as HDF5's gzip
    (deflate) filter reads it: with ISA-L (the ``isal`` package, ``acousim[fast]``)
    at :data:`ISAL_LEVEL`, about five times faster than zlib at level 1, the
    images' chunks 2 % larger, else zlib at :data:`GZIP_LEVEL`.  Any inflater (HDF5's, MATLAB's,
    HDFView's) reads either stream."""
    if _isal_zlib is not None:
        return _isal_zlib.compress(data, ISAL_LEVEL)
    import zlib

    return zlib.compress(data, GZIP_LEVEL)


try:  # optional: a faster deflate, the same stream format
    from isal import isal_zlib as _isal_zlib
except ImportError:  # pragma: no cover - depends on the install
    _isal_zlib = None


def write_peaks_csv(
    path: str | Path,
    recordings: Sequence[P.Recording],
    images: Sequence[Mapping[str, P.Image]],
    indices: Sequence[int] | None = None,
    *,
    threshold_db: float = PEAK_THRESHOLD_DB,
    tables: Sequence[Mapping[str, P.PeakTable]] | None = None,
) -> Path:
    """Write the peaks of every image within `threshold_db` (dB) of its strongest cell
    to a CSV file (atomically), one row per peak (:func:`acousim.peak_table`: the
    columns of :class:`processing.PeakRow`), strongest first per image; `tables`: as
    :func:`write_image_data` takes them."""
    indices = list(indices) if indices is not None else list(range(len(recordings)))
    if tables is None:
        tables = peak_tables(recordings, images, indices, threshold_db)
    return write_text(path, peaks_csv_text(tables))


def peaks_csv_text(tables: Sequence[Mapping[str, P.PeakTable]]) -> str:
    """The text of ``peaks.csv`` for the images' peak tables (:func:`peak_tables`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(PEAK_COLUMNS)
    for table in tables:
        for rows in table.values():
            w.writerows([_fmt(row.as_dict().values()) for row in rows])
    return buf.getvalue()


def _fmt(values) -> list:
    """A row's cells: booleans as 0/1, no value (None, NaN) as empty, numbers in full
    (Python's shortest text that reads back as the same float64: the cells equal
    images.h5's axes and the Python rows exactly)."""
    out = []
    for v in values:
        if isinstance(v, (bool, np.bool_)):
            out.append(int(v))
        elif v is None or (isinstance(v, (float, np.floating)) and v != v):
            out.append("")
        elif isinstance(v, str):
            out.append(v)
        elif isinstance(v, (int, np.integer)):
            out.append(int(v))
        else:
            out.append(repr(float(v)))
    return out
