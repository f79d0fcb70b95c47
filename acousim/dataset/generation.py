"""Generating a dataset: sample i is a pure function of (spec, seed, i).

Samples are grouped into shards of ``shard_size``; a worker computes a whole shard,
writes it to a temporary name and renames it when complete, with a sidecar JSON
(its samples' parameters and the shard's sha256).  Generation steps:

0. check the spec (its scenes' regions, the first sample) before writing anything;
1. lock the output folder (one generator per folder; the lock dies with its process),
   remove temporary files an interrupted run left, refuse a folder whose shards were
   made from other files (the spec, its scenes and the files they read: inputs.json);
2. keep every finished shard whose bytes match its sidecar's sha256, redo the rest;
3. compute the missing shards here, in a local pool (workers exit when the main
   process dies) or on a Dask cluster (an unreachable scheduler fails at once);
4. assemble the manifest from the sidecars.

HDF5 is written without timestamps, so the same spec gives the same bytes on any
number of workers.  The file layout is in ``docs/dataset-format.md``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np

import processing as P
from acousim.dataset.chirp_shards import capture_samples, write_chirp_shard
from acousim.dataset.runners import run_dask, run_pool
from acousim.dataset.safety import check_scheduler, locked, sha256_file
from acousim.dataset.samples import (  # noqa: F401  (re-exported)
    _clear,
    _motion,
    _pose,
    _relative,
    _scene,
    _scene_path,
    _varied_scene,
    _world_caster,
    check_regions,
    sample_array,
    sample_parameters,
    simulate_sample,
)
from acousim.dataset.spec import DatasetSpec, load_spec
from acousim.imaging.labels import SAMPLE_FIELDS, sample_labels
from acousim.viz.fan import DYNAMIC_RANGE_DB
from processing.base import interrupt
from processing.base.atomic import TEMP_PREFIX, atomic_path, write_text
from processing.base.errors import InputError
from processing.imaging.snapshot import Stft, range_axis

__all__ = [
    "sample_parameters",
    "make_sample",
    "simulate_sample",
    "write_shard",
    "generate",
    "shard_name",
    "kept_shards",
    "usable_spec",
    "image_range_m",
    "recording_samples",
    "SHARD_SCHEMA",
]

MANIFEST = "manifest.json"
SHARD_SCHEMA = "acousim.dataset.shard"
SHARD_SCHEMA_VERSION = 3
UNITS = {
    "raw": "1",
    "snapshot": "1",
    "range_m": "m",
    "range_index": "1",
    "labels/position_sensor_m": "m",
    "labels/amplitude": "1",
    "labels/order": "1",
    "labels/emitter": "1",
    "labels/depth_m": "m",
    **{key: units for key, _, _, units, _ in SAMPLE_FIELDS},
}
"""Units of every stored array (``image/<method>``: dB relative to the image's maximum)."""
DIMS = {
    "raw": "microphone,time",
    "snapshot": "microphone,kept_range_bin",
    "range_m": "range",
    "range_index": "kept_range_bin",
    "labels/position_sensor_m": "path,xyz",
    "labels/amplitude": "path",
    "labels/order": "path",
    "labels/emitter": "path",
    "labels/depth_m": "elevation,azimuth",
    **{key: dims for key, _, _, _, dims in SAMPLE_FIELDS},
}


def _units_dims(name: str) -> tuple[str, str]:
    """The ``units`` and ``dims`` attributes of a stored array."""
    if name.startswith("peaks/"):
        return ("1", "peak,cell") if name.endswith("/index") else ("dB", "peak")
    default = "1" if name.startswith("label_map/") else "dB"  # an image's dB, a label map's 1
    return UNITS.get(name, default), DIMS.get(name, "range,elevation,azimuth")


def shard_name(k: int) -> str:
    return f"shard_{k:05d}.h5"


def make_sample(spec: DatasetSpec, i: int) -> tuple[dict, dict]:
    """(arrays, parameters) of sample i.

    Images are on the spec's grid (:func:`image_range_m`, the spec's directions): the
    same shape (R, E, A) for every sample, whatever its air. The parameters gain
    ``frequency_hz`` (the steering frequency of the snapshot and images),
    ``speed_of_sound_m_s``, ``range_step_m``, ``array`` (its name), and the
    recording's ``sample_rate_hz`` and ``emission_index`` (the sample of ``raw`` where
    the call starts).
    """
    axis = image_range_m(spec)
    rec, params, scene, pose = simulate_sample(spec, i, n_samples=recording_samples(spec))
    st = spec.store
    arrays: dict[str, np.ndarray] = {}
    if st.raw:
        arrays["raw"] = rec.samples.astype(np.float32)
    grid = P.Grid.degrees(st.azimuth_deg, st.elevation_deg, st.step_deg)
    settings = P.ProcessingSettings(
        energy_fraction=st.energy_fraction,
        grid=grid,
        max_bins=st.max_bins,
        range_limits_m=(float(axis[0]), float(axis[-1])),
        range_step_m=st.range_step_m,
    )
    snap = P.recording_snapshot(rec, settings)
    index = _on_axis(axis, snap.range_m)
    if st.snapshot or st.images:
        arrays["range_m"] = axis  # float64: exactly regular, the same in every sample
        arrays["range_index"] = index.astype(np.int32)
    if st.snapshot:
        arrays["snapshot"] = snap.data.astype(np.complex64)
    if st.images:
        images = P.acoustic_images(rec, st.images, settings, snapshot=snap)
        for m, img in images.items():
            arrays.update(_image_arrays(m, img, axis, index, st))
    if st.labels:
        truth = rec.truth
        arrays["labels/position_sensor_m"] = truth.position_sensor_m.astype(np.float32)
        arrays["labels/amplitude"] = truth.amplitude.astype(np.float32)
        arrays["labels/order"] = truth.order.astype(np.int8)
        emitters = _emitters(params, spec)
        arrays["labels/emitter"] = _emitter_index(truth, emitters, params)
        params = {**params, "emitters": emitters}
        # what the sensor sees, and the images' label maps (acousim.imaging.labels)
        dr = DYNAMIC_RANGE_DB
        arrays.update(sample_labels(rec, images if st.images else {}, axis, settings.window, dr))
    if st.depth_map:
        arrays["labels/depth_m"] = _depth_map(_scene_path(params, spec), pose, grid, scene)
    if st.labels and rec.truth is not None and rec.truth.object_index is not None:
        params = {**params, "object_names": list(rec.truth.object_names)}
    params = {
        **params,
        "frequency_hz": snap.frequency_hz,
        "speed_of_sound_m_s": rec.speed_of_sound_m_s,
        "range_step_m": st.range_step_m,
        "array": rec.array.name,
        "sample_rate_hz": rec.sample_rate_hz,
        "emission_index": int(rec.emission_index),
    }
    return arrays, params


def _emitters(params: dict, spec: DatasetSpec) -> list[str]:
    """The names of the sonars whose calls a sample's paths may carry: a rig's
    sonars, in the rig's order; a single sensor's scene: ``["sensor"]``."""
    rig = _scene(_scene_path(params, spec)).rig
    return ["sensor"] if rig is None else [s.name for s in rig.sonars]


def _emitter_index(truth, emitters: list[str], params: dict) -> np.ndarray:
    """(N,) int8: each path's emitter as an index into `emitters` (the sample's own
    sonar for a recording without per-path emitters)."""
    own = emitters.index(params.get("sensor", emitters[0]))
    if truth.emitter is None:
        return np.full(truth.order.shape, own, np.int8)
    index = {name: k for k, name in enumerate(emitters)}
    return np.array([index[str(e)] for e in truth.emitter], np.int8).reshape(-1)


def image_range_m(spec: DatasetSpec) -> np.ndarray:
    """The range axis (R,), m, of every image of the spec: ``min_range_m + k *
    range_step_m`` up to ``max_range_m`` (unset: the largest ``max_range_m`` of the
    spec's scenes). It does not depend on the speed of sound."""
    st = spec.store
    hi = st.max_range_m
    if hi is None:
        hi = max(_scene(str(c.file)).simulation.max_range_m for c in spec.scenes)
    stft = Stft(range_step_m=st.range_step_m)
    return range_axis(stft, (st.min_range_m, max(hi, st.min_range_m)), 0, 1.0, 1.0)


def recording_samples(spec: DatasetSpec) -> int:
    """Samples of every recording of the spec: what the last range bin's STFT frame
    needs in the slowest air the spec can draw (so every range bin has data), the
    same for every sample (``raw`` is (M, T) with one T)."""

    window = P.ProcessingSettings().window
    return capture_samples(spec, max_range_m=float(image_range_m(spec)[-1])) + window


def _on_axis(axis: np.ndarray, ranges: np.ndarray) -> np.ndarray:
    """Indices (R_kept,) into `axis` of the snapshot's ranges (exactly its values)."""
    index = np.searchsorted(axis, ranges - (axis[1] - axis[0] if axis.size > 1 else 1) / 4)
    if index.size and not np.allclose(axis[index], ranges, rtol=0, atol=1e-9):
        raise AssertionError("snapshot bins off the range axis")  # pragma: no cover
    return index


def _image_arrays(method: str, img: P.Image, axis, index, st) -> dict[str, np.ndarray]:
    """An image on the whole range axis in dB (R, E, A) float16: the gated range bins
    (power 0) hold the floor, ``st.floor_db``, as do cells below it; its peaks
    (``peaks/<method>/index`` (P, 3) int32: range bin, elevation, azimuth; and
    ``level_db`` (P,) float32), the strongest ``st.max_peaks`` at least
    ``st.peak_threshold_db``, found on that whole image."""
    power = np.zeros((axis.size, img.elevation_rad.size, img.azimuth_rad.size))
    power[index] = img.power
    # the range bins holding a cell above the threshold, with their neighbours: the
    # whole image's peaks (no other cell can be one, and each bin keeps its own
    # neighbours), searched in a tenth of the image
    hot = power >= power.max() * 10 ** (st.peak_threshold_db / 10) * (1 - 1e-9)
    hot = np.flatnonzero(hot.any(axis=(1, 2)))
    rows = np.unique(np.clip(np.concatenate([hot - 1, hot, hot + 1]), 0, axis.size - 1))
    near = dataclasses.replace(img, power=power[rows], range_m=axis[rows])
    peaks = P.find_peaks(near, st.peak_threshold_db, max_peaks=st.max_peaks)
    cells = np.stack(
        [
            _nearest(axis, peaks.range_m),
            _nearest(img.elevation_rad, peaks.elevation_rad),
            _nearest(img.azimuth_rad, peaks.azimuth_rad),
        ],
        axis=-1,
    ).reshape(-1, 3)
    return {
        f"image/{method}": _on_floor(img.db(floor_db=st.floor_db), axis.size, index, st),
        f"peaks/{method}/index": cells.astype(np.int32),
        f"peaks/{method}/level_db": peaks.level_db.astype(np.float32),
    }


def _on_floor(db: np.ndarray, n: int, index: np.ndarray, st) -> np.ndarray:
    """The kept bins' image in dB (R_kept, E, A) on the whole range axis (n, E, A),
    float16; the gated bins hold the floor."""
    out = np.full((n, *db.shape[1:]), st.floor_db, np.float16)
    out[index] = db.astype(np.float16)
    return out


def _nearest(axis: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Index of the element of `axis` nearest each value (values lie on the axis)."""
    return np.abs(np.asarray(values)[:, None] - axis[None, :]).argmin(axis=1)


def _depth_map(scene_file: str, pose, grid: P.Grid, scene) -> np.ndarray:
    """Distance (m) to the nearest surface along each grid direction (E, A); inf where
    the ray leaves the scene without meeting a surface."""
    caster = _world_caster(scene_file)
    d = grid.directions().reshape(-1, 3) @ pose.rotation.T
    if caster is None:
        return np.full(grid.shape, np.inf, np.float32)
    origin = pose.to_world(scene.sensor.array.positions_m.mean(axis=0))
    t, _ = caster.first_hit(np.broadcast_to(origin, d.shape), d)
    return t.reshape(grid.shape).astype(np.float32)


def _group(parent: h5py.Group, name: str) -> h5py.Group:
    """A group without modification times (h5py's create_group stores them, which
    would make the same content different bytes from one run to the next)."""
    gcpl = h5py.h5p.create(h5py.h5p.GROUP_CREATE)
    gcpl.set_obj_track_times(False)
    gcpl.set_link_creation_order(h5py.h5p.CRT_ORDER_TRACKED | h5py.h5p.CRT_ORDER_INDEXED)
    return h5py.Group(h5py.h5g.create(parent.id, name.encode(), gcpl=gcpl))


def write_shard(spec: DatasetSpec, k: int, out_dir: str | Path) -> dict:
    """Compute and write shard k (atomically); returns its sidecar record."""
    out = Path(out_dir)
    lo, hi = k * spec.shard_size, min((k + 1) * spec.shard_size, spec.samples)
    final = out / shard_name(k)
    records = []
    t0 = time.perf_counter()
    if spec.format == "chirp":
        records, digest, size = write_chirp_shard(spec, k, lo, hi, final)
    else:
        records, digest, size = _write_acousim_shard(spec, k, lo, hi, final)
    side = {
        "shard": k,
        "file": final.name,
        "sha256": digest,
        "samples": records,
        "seconds": time.perf_counter() - t0,
        "bytes": size,
    }
    write_text(out / f"{final.stem}.json", json.dumps(side, sort_keys=True))
    return side


def _write_acousim_shard(spec: DatasetSpec, k: int, lo: int, hi: int, final: Path):
    """Shard k in our format (docs/dataset-format.md): (records, sha256, bytes)."""
    records = []
    with atomic_path(final) as tmp:
        arrays_seen: dict[str, P.Array] = {}
        with h5py.File(tmp, "w", track_order=True, libver="latest") as f:
            f.attrs["schema"] = np.bytes_(SHARD_SCHEMA)
            f.attrs["schema_version"] = SHARD_SCHEMA_VERSION
            f.attrs["spec_sha256"] = np.bytes_(spec.sha256)
            _write_axes(f, spec)
            for i in range(lo, hi):
                arrays, params = make_sample(spec, i)
                g = _group(f, f"{i - lo:05d}")
                for name, a in arrays.items():
                    *parents, leaf = name.split("/")
                    parent = g
                    for p in parents:
                        parent = parent[p] if p in parent else _group(parent, p)
                    ds = _dataset(parent, leaf, a, spec.compression)
                    units, dims = _units_dims(name)
                    ds.attrs["units"] = np.bytes_(units)
                    ds.attrs["dims"] = np.bytes_(dims)
                    if name.startswith("image/"):
                        ds.attrs["floor_db"] = spec.store.floor_db
                # fixed-length bytes: no global heap, whose layout varies between processes
                g.attrs["params"] = np.bytes_(json.dumps(params, sort_keys=True))
                records.append({**params, "shard": k, "offset": i - lo})
                name = params["array"]
                if name not in arrays_seen:
                    arrays_seen[name] = sample_array(params, spec)
            geometry = _group(f, "arrays")
            for name, array in sorted(arrays_seen.items()):
                a = _group(geometry, name)
                _dataset(a, "positions_m", array.positions_m, None).attrs["units"] = b"m"
                _dataset(a, "emitter_m", array.emitter_m, None).attrs["units"] = b"m"
        digest = hashlib.sha256(tmp.read_bytes()).hexdigest()
        size = tmp.stat().st_size
    return records, digest, size


def _dataset(parent: h5py.Group, name: str, a: np.ndarray, compression) -> h5py.Dataset:
    """A dataset with HDF5's fletcher32 checksum (a corrupted chunk fails to read),
    without timestamps; its chunks written at once, so that file space is allocated in
    creation order: left to garbage collection, the chunk cache is flushed when the
    last reference goes, later when something (Dask's profiler sampling this frame)
    holds one, and the bytes differ."""
    a = np.asarray(a)
    ds = parent.create_dataset(
        name,
        data=a,
        compression=compression if a.size > 64 else None,
        chunks=a.shape if a.size else None,
        fletcher32=bool(a.size),
        track_times=False,
    )
    ds.flush()
    return ds


def _write_axes(f: h5py.File, spec: DatasetSpec) -> None:
    """The image grid's axes (degrees, as in the spec; the range axis in m) and the
    range settings."""
    st = spec.store
    grid = P.Grid.degrees(st.azimuth_deg, st.elevation_deg, st.step_deg)
    axes = _group(f, "axes")
    for name, values in (
        ("azimuth_deg", np.rad2deg(grid.azimuth_rad)),
        ("elevation_deg", np.rad2deg(grid.elevation_rad)),
    ):
        _dataset(axes, name, values, None).attrs["units"] = b"deg"
    _dataset(axes, "range_m", image_range_m(spec), None).attrs["units"] = b"m"
    axes.attrs["min_range_m"] = st.min_range_m
    axes.attrs["range_step_m"] = st.range_step_m
    axes.attrs["floor_db"] = st.floor_db
    axes.attrs["max_peaks"] = st.max_peaks
    axes.attrs["peak_threshold_db"] = st.peak_threshold_db
    axes.attrs["energy_fraction"] = st.energy_fraction


def _shard_job(args: tuple[str, int, str, str | None]) -> dict:
    """One shard, with BLAS on one thread: the summation order (and so every bit of
    the result) must not depend on the worker's thread settings (Dask's workers run
    single-threaded BLAS, a local process may not). `args`: the spec's path, the
    shard, the output folder, the quality preset given (None: the spec's)."""
    from threadpoolctl import threadpool_limits

    spec_path, k, out, quality = args
    spec = with_quality(load_spec(spec_path), quality)
    changed = _changed(json.loads((Path(out) / INPUTS).read_text()), _record(spec))
    if changed:  # a file edited while the dataset is generated
        raise InputError(f"changed during the run: {'; '.join(changed)}", file=spec.source)
    with threadpool_limits(1):
        return write_shard(spec, k, out)


def kept_shards(spec_path: str | Path, out_dir: str | Path) -> tuple[int, int]:
    """(finished shards in `out_dir`, shards of the spec): a finished shard has its
    file and its sidecar; a resumed run checks their sha256 and keeps them."""
    spec = load_spec(spec_path)
    out = Path(out_dir)
    kept = sum(
        (out / shard_name(k)).is_file() and (out / f"shard_{k:05d}.json").is_file()
        for k in range(spec.n_shards)
    )
    return kept, spec.n_shards


def _done(spec: DatasetSpec, out: Path) -> tuple[set[int], list[int]]:
    """Finished shards whose bytes match their sidecar's sha256, and the shards found
    damaged (removed, to be redone)."""
    done, damaged = set(), []
    for k in range(spec.n_shards):
        shard, side = out / shard_name(k), out / f"shard_{k:05d}.json"
        if not (shard.is_file() and side.is_file()):
            continue
        try:
            ok = sha256_file(shard) == json.loads(side.read_text())["sha256"]
        except (ValueError, KeyError, TypeError):
            ok = False
        if ok:
            done.add(k)
        else:
            damaged.append(k)
            shard.unlink()
            side.unlink()
    return done, damaged


def with_quality(spec: DatasetSpec, quality: str | None) -> DatasetSpec:
    """`spec` with every scene under the `quality` preset (None: as the spec says)."""
    return spec if quality is None else dataclasses.replace(spec, quality=quality)


def usable_spec(spec_path: str | Path) -> DatasetSpec:
    """The spec, read and checked as far as can be before any work (nothing is
    written): each random-pose scene's region has a usable pose, and the first
    sample's parameters can be drawn. A :class:`SpecError` otherwise."""
    spec = load_spec(spec_path)
    check_regions(spec)
    sample_parameters(spec, 0)
    return spec


def generate(
    spec_path: str | Path,
    out_dir: str | Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    quality: str | None = None,
) -> dict:
    """Generate (or finish) a dataset; returns the manifest.

    `quality`: every scene's ``simulation.quality`` preset ("fast", "default",
    "reference"; None: the spec's ``[dataset] quality``, unset there: each scene
    file's), recorded in inputs.json and the manifest: a folder made under another
    quality is not resumed.

    The manifest's ``summary`` adds ``damaged_shards``: finished shards whose bytes no
    longer matched their recorded sha256 and were redone (their indices; manifest.json
    lists their file names).
    """
    spec = with_quality(usable_spec(spec_path), quality)
    out = Path(out_dir)
    if scheduler:
        check_scheduler(scheduler)
    out.mkdir(parents=True, exist_ok=True)
    with locked(out):
        for stale in out.glob(f"{TEMP_PREFIX}*"):
            stale.unlink()  # an interrupted run's incomplete file: redone
        _claim(spec, out)
        done, damaged = _done(spec, out)
        todo = [k for k in range(spec.n_shards) if k not in done]
        jobs = [(str(Path(spec_path).resolve()), k, str(out.resolve()), quality) for k in todo]
        done_count = spec.n_shards - len(todo)
        t0 = time.perf_counter()
        if progress:
            progress(done_count, spec.n_shards)

        def step() -> None:
            nonlocal done_count
            done_count += 1
            if progress:
                progress(done_count, spec.n_shards)

        if scheduler:
            run_dask(_shard_job, jobs, scheduler, step)
        elif workers > 1 and len(jobs) > 1:
            run_pool(_shard_job, jobs, workers, out, step)
        else:
            for job in jobs:
                interrupt.check()
                _shard_job(job)
                step()
        elapsed = time.perf_counter() - t0
        manifest = _manifest(spec, out, elapsed, todo, damaged)
    manifest["summary"]["damaged_shards"] = damaged
    return manifest


INPUTS = "inputs.json"
"""The files a folder's shards were made from, with their sha256 (``spec.inputs``)."""


def _claim(spec: DatasetSpec, out: Path) -> None:
    """Make `out` the folder of `spec`'s dataset: a folder without a shard is free (a
    failed run's leftovers are replaced); one with shards must have been made from the
    same files (the spec, its scenes and the files they read), byte for byte, else an
    InputError naming each file that changed."""
    mine = _record(spec)
    shards = [*out.glob("shard_*.h5"), *out.glob("shard_*.json")]
    recorded = out / INPUTS
    if shards and not recorded.is_file():
        raise InputError(
            "holds shards without a record of the scene files they were made from (an "
            "older acousim, or not a dataset folder): a resumed run cannot check them; "
            "use a new folder",
            file=out,
        )
    if shards:
        try:
            theirs = json.loads(recorded.read_text())
            changed = _changed(theirs, mine)
        except (ValueError, KeyError, TypeError, AttributeError):
            raise InputError("unreadable; use a new folder", file=recorded) from None
        if changed:
            raise InputError(
                "holds shards made from other files: "
                + "; ".join(changed)
                + ". Resuming would mix samples of both; use a new folder (or restore "
                "the files)",
                file=out,
            )
    write_text(recorded, json.dumps(mine, indent=1, sort_keys=True))
    (out / "spec.sha256").unlink(missing_ok=True)  # an older acousim's record


def _record(spec: DatasetSpec) -> dict:
    """The folder's record of the files its shards are made from (``inputs.json``)."""
    return {"spec": Path(spec.source).name, "files": spec.inputs, "quality": spec.quality}


def _changed(theirs: dict, mine: dict) -> list[str]:
    """What differs between two records of a folder's files: one phrase per file."""
    old, new = dict(theirs["files"]), dict(mine["files"])
    out = []
    if theirs.get("quality") != mine["quality"]:  # an older record: the scenes' own
        out.append(
            f"another quality (the shards: {_quality(theirs.get('quality'))}; this run: "
            f"{_quality(mine['quality'])})"
        )
    old_spec, new_spec = old.pop(theirs["spec"]), new.pop(mine["spec"])
    if old_spec != new_spec:
        out.append(f"another spec (sha256 {old_spec[:12]}..., {mine['spec']}: {new_spec[:12]}...)")
    for name in sorted(set(old) | set(new)):
        if name not in new:
            out.append(f"{name} is no longer used")
        elif name not in old:
            out.append(f"{name} is new")
        elif old[name] != new[name]:
            out.append(f"{name} changed (sha256 {old[name][:12]}... now {new[name][:12]}...)")
    return out


def _quality(q: str | None) -> str:
    return "each scene's own" if q is None else repr(q)


def _manifest(
    spec: DatasetSpec, out: Path, elapsed: float, computed: list[int], damaged: list[int]
) -> dict:
    """manifest.json, written; ``damaged_shards``: the shards this run found damaged
    (bytes not matching their sidecar's sha256) and redone. The file holds what a
    reader needs at open (the shards, their sha256 and sample counts: sample i is
    in shard i // shard_size), not the samples' parameters, which are in the
    sidecars and the shards (about 1 kB a sample: a million samples' manifest was
    1 GB to parse); the dict returned adds them (``sample_table``) and ``summary``."""
    sides = [json.loads((out / f"shard_{k:05d}.json").read_text()) for k in range(spec.n_shards)]
    samples = [s for side in sides for s in side["samples"]]
    total = sum(s["bytes"] for s in sides)
    manifest = {
        "schema": "acousim.dataset",
        "schema_version": SHARD_SCHEMA_VERSION,
        "name": spec.name,
        "spec": Path(spec.source).name,
        "spec_sha256": spec.sha256,
        "inputs": spec.inputs,
        "samples": len(samples),
        "shard_size": spec.shard_size,
        "shard_format": spec.format,
        "quality": spec.quality,
        "shards": [
            {
                "file": s["file"],
                "sha256": s["sha256"],
                "bytes": s["bytes"],
                "samples": len(s["samples"]),
            }
            for s in sides
        ],
        "damaged_shards": [shard_name(k) for k in damaged],
    }
    write_text(out / MANIFEST, json.dumps(manifest, indent=1, sort_keys=True))
    manifest["sample_table"] = samples
    made = sum(len(sides[k]["samples"]) for k in computed)
    manifest["summary"] = {
        "bytes_per_sample": total / max(len(samples), 1),
        "seconds": elapsed,
        "samples_computed": made,
        "samples_per_second": made / elapsed if elapsed > 0 else 0.0,
    }
    return manifest
