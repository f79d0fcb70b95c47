"""Generating a dataset: sample i is a pure function of (spec, seed, i).

Samples are grouped into shards of ``shard_size``; a worker computes a whole shard,
writes it to a temporary name and renames it when complete, with a sidecar JSON
(its samples' parameters and the shard's sha256).  Generation steps:

1. lock the output folder (one generator per folder; the lock dies with its process),
   remove temporary files an interrupted run left, refuse another spec's folder;
2. keep every finished shard whose bytes match its sidecar's sha256, redo the rest;
3. compute the missing shards here, in a local pool (workers exit when the main
   process dies) or on a Dask cluster (an unreachable scheduler fails at once);
4. assemble the manifest from the sidecars.

HDF5 is written without timestamps, so the same spec gives the same bytes on any
number of workers.  The file layout is in ``docs/dataset-format.md``.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np

import processing as P
from acousim.labels import SAMPLE_FIELDS, sample_labels
from acousim.viz.fan import DYNAMIC_RANGE_DB
from processing import interrupt
from processing.atomic import TEMP_PREFIX, atomic_path, write_text
from processing.errors import InputError

from .runners import run_dask, run_pool
from .safety import check_scheduler, locked, sha256_file
from .samples import (  # noqa: F401  (re-exported)
    _clear,
    _motion,
    _pose,
    _relative,
    _scene,
    _scene_path,
    _varied_scene,
    _world_caster,
    sample_parameters,
    simulate_sample,
)
from .spec import DatasetSpec, load_spec

__all__ = [
    "sample_parameters",
    "make_sample",
    "simulate_sample",
    "write_shard",
    "generate",
    "shard_name",
    "SHARD_SCHEMA",
]

MANIFEST = "manifest.json"
SHARD_SCHEMA = "acousim.dataset.shard"
SHARD_SCHEMA_VERSION = 2
UNITS = {
    "raw": "1",
    "snapshot": "1",
    "range_m": "m",
    "range_index": "1",
    "labels/position_sensor_m": "m",
    "labels/amplitude": "1",
    "labels/order": "1",
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
    "labels/depth_m": "elevation,azimuth",
    **{key: dims for key, _, _, _, dims in SAMPLE_FIELDS},
}


def _default_units(name: str) -> str:
    """The units of an array not in UNITS: an image's dB, a label map's "1"."""
    return "1" if name.startswith("label_map/") else "dB"


def shard_name(k: int) -> str:
    return f"shard_{k:05d}.h5"


def make_sample(spec: DatasetSpec, i: int) -> tuple[dict, dict]:
    """(arrays, parameters) of sample i.

    The parameters gain ``frequency_hz`` (the steering frequency of the snapshot and
    images), ``speed_of_sound_m_s``, ``range_step_m`` and ``array`` (its name).
    """
    rec, params, scene, pose = simulate_sample(spec, i)
    st = spec.store
    arrays: dict[str, np.ndarray] = {}
    if st.raw:
        arrays["raw"] = rec.samples.astype(np.float32)
    grid = P.Grid.degrees(st.azimuth_deg, st.elevation_deg, st.step_deg)
    settings = P.ProcessingSettings(
        energy_fraction=st.energy_fraction,
        grid=grid,
        max_bins=st.max_bins,
        range_limits_m=(st.min_range_m, scene.simulation.max_range_m),
    )
    snap = P.recording_snapshot(rec, settings)
    axis, index = _range_axis(rec, settings, snap)
    if st.snapshot or st.images:
        arrays["range_m"] = axis  # float64: exactly regular
        arrays["range_index"] = index.astype(np.int32)
    if st.snapshot:
        arrays["snapshot"] = snap.data.astype(np.complex64)
    if st.images:
        images = P.acoustic_images(rec, st.images, settings, snapshot=snap)
        for m, img in images.items():
            # on the regular range axis; bins the energy gate left out: NaN (no data)
            dense = np.full((axis.size, *grid.shape), np.nan, np.float16)
            dense[index] = img.db(floor_db=-60).astype(np.float16)
            arrays[f"image/{m}"] = dense
    if st.labels:
        truth = rec.truth
        arrays["labels/position_sensor_m"] = truth.position_sensor_m.astype(np.float32)
        arrays["labels/amplitude"] = truth.amplitude.astype(np.float32)
        arrays["labels/order"] = truth.order.astype(np.int8)
        # what the sensor sees, and the images' label maps (acousim.labels)
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
        "range_step_m": snap.bin_range_m,
        "array": rec.array.name,
    }
    return arrays, params


def _range_axis(
    rec: P.Recording, settings: P.ProcessingSettings, snap
) -> tuple[np.ndarray, np.ndarray]:
    """The regular range axis (R,) of every STFT frame within the range limits (m), and
    the index (R_kept,) of each kept snapshot bin on it."""
    hop = settings.window - settings.overlap
    frames = (rec.n_samples - settings.window) // hop + 1
    t = (np.arange(frames) * hop + settings.window // 2 - rec.emission_index) / rec.sample_rate_hz
    r = rec.speed_of_sound_m_s * t / 2
    lo, hi = settings.range_limits_m
    axis = r[(r >= lo) & (r <= hi)]
    index = np.searchsorted(axis, snap.range_m - snap.bin_range_m / 4)
    if index.size and not np.allclose(axis[index], snap.range_m, rtol=0, atol=1e-9):
        raise AssertionError("snapshot bins off the regular range axis")  # pragma: no cover
    return axis, index


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
        from .chirp_shards import write_chirp_shard

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
                    ds.attrs["units"] = np.bytes_(UNITS.get(name, _default_units(name)))
                    ds.attrs["dims"] = np.bytes_(DIMS.get(name, "range,elevation,azimuth"))
                # fixed-length bytes: no global heap, whose layout varies between processes
                g.attrs["params"] = np.bytes_(json.dumps(params, sort_keys=True))
                records.append({**params, "shard": k, "offset": i - lo})
                name = params["array"]
                if name not in arrays_seen:
                    arrays_seen[name] = _scene(_scene_path(params, spec)).sensor.array
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
    """The image grid's axes (degrees, as in the spec) and the range settings."""
    st = spec.store
    grid = P.Grid.degrees(st.azimuth_deg, st.elevation_deg, st.step_deg)
    axes = _group(f, "axes")
    for name, values in (
        ("azimuth_deg", np.rad2deg(grid.azimuth_rad)),
        ("elevation_deg", np.rad2deg(grid.elevation_rad)),
    ):
        _dataset(axes, name, values, None).attrs["units"] = b"deg"
    axes.attrs["min_range_m"] = st.min_range_m
    axes.attrs["energy_fraction"] = st.energy_fraction


def _shard_job(args: tuple[str, int, str]) -> dict:
    """One shard, with BLAS on one thread: the summation order (and so every bit of
    the result) must not depend on the worker's thread settings (Dask's workers run
    single-threaded BLAS, a local process may not)."""
    from threadpoolctl import threadpool_limits

    spec_path, k, out = args
    with threadpool_limits(1):
        return write_shard(load_spec(spec_path), k, out)


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


def generate(
    spec_path: str | Path,
    out_dir: str | Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict:
    """Generate (or finish) a dataset; returns the manifest.

    The manifest's ``summary`` adds ``damaged_shards``: finished shards whose bytes no
    longer matched their recorded sha256 and were redone.
    """
    spec = load_spec(spec_path)
    out = Path(out_dir)
    if scheduler:
        check_scheduler(scheduler)
    out.mkdir(parents=True, exist_ok=True)
    with locked(out):
        for stale in out.glob(f"{TEMP_PREFIX}*"):
            stale.unlink()  # an interrupted run's incomplete file: redone
        existing = out / "spec.sha256"
        if existing.is_file() and existing.read_text().strip() != spec.sha256:
            raise InputError(
                f"holds a dataset of another spec (sha256 {existing.read_text().strip()[:12]}"
                "...); use a new folder",
                file=out,
            )
        write_text(existing, spec.sha256 + "\n")
        done, damaged = _done(spec, out)
        todo = [k for k in range(spec.n_shards) if k not in done]
        if todo:  # a spec that cannot make its first sample fails here, before any worker
            sample_parameters(spec, todo[0] * spec.shard_size)
        jobs = [(str(Path(spec_path).resolve()), k, str(out.resolve())) for k in todo]
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
        manifest = _manifest(spec, out, elapsed, todo)
    manifest["summary"]["damaged_shards"] = damaged
    return manifest


def _manifest(spec: DatasetSpec, out: Path, elapsed: float, computed: list[int]) -> dict:
    sides = [json.loads((out / f"shard_{k:05d}.json").read_text()) for k in range(spec.n_shards)]
    samples = [s for side in sides for s in side["samples"]]
    total = sum(s["bytes"] for s in sides)
    manifest = {
        "schema": "acousim.dataset",
        "schema_version": SHARD_SCHEMA_VERSION,
        "name": spec.name,
        "spec": Path(spec.source).name,
        "spec_sha256": spec.sha256,
        "samples": len(samples),
        "shard_size": spec.shard_size,
        "shard_format": spec.format,
        "shards": [
            {
                "file": s["file"],
                "sha256": s["sha256"],
                "bytes": s["bytes"],
                "samples": len(s["samples"]),
            }
            for s in sides
        ],
        "sample_table": samples,
    }
    write_text(out / MANIFEST, json.dumps(manifest, indent=1, sort_keys=True))
    made = sum(len(sides[k]["samples"]) for k in computed)
    manifest["summary"] = {
        "bytes_per_sample": total / max(len(samples), 1),
        "seconds": elapsed,
        "samples_computed": made,
        "samples_per_second": made / elapsed if elapsed > 0 else 0.0,
    }
    return manifest
