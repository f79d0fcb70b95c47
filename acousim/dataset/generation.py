"""Generating a dataset: sample i is a pure function of (spec, seed, i).

Samples are grouped into shards of ``shard_size``; a worker computes a whole shard,
writes it to a temporary name and renames it when complete, with a sidecar JSON
(its samples' parameters and the shard's sha256).  Resuming skips every shard that
exists (a shard exists only once complete) and redoes the rest; the manifest is
assembled from the sidecars at the end.  HDF5 is written without timestamps, so the
same spec gives the same bytes on any number of workers.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from functools import lru_cache
from pathlib import Path

import h5py
import numpy as np

import processing as P

from .spec import DatasetSpec, load_spec

__all__ = ["sample_parameters", "make_sample", "write_shard", "generate", "shard_name"]

MANIFEST = "manifest.json"


def shard_name(k: int) -> str:
    return f"shard_{k:05d}.h5"


@lru_cache(maxsize=8)
def _scene(path: str):
    from acousim.scene import load_scene

    return load_scene(path)


@lru_cache(maxsize=4)
def _world_caster(path: str):
    """Geometry for collision checks, built once per scene file and process."""
    from acousim.trace.embree import RayCaster
    from acousim.trace.geometry import build_world

    scene = _scene(path)
    if not scene.meshes:
        return None
    return RayCaster(build_world(scene).triangles, threads=1)


def _clear(path: str, position: np.ndarray, clearance: float) -> bool:
    caster = _world_caster(path)
    if caster is None:
        return True
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    t, f = caster.first_hit(np.broadcast_to(position, dirs.shape), dirs)
    return bool(np.all(t >= clearance)) and bool(np.all(f >= 0))  # inside and clear


def sample_parameters(spec: DatasetSpec, i: int) -> dict:
    """The random choices of sample i: scene, pose, conditions, noise seed."""
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, i]))
    w = np.array([s.weight for s in spec.scenes])
    k = int(rng.choice(len(spec.scenes), p=w / w.sum()))
    choice = spec.scenes[k]
    scene = _scene(str(choice.file))
    if choice.poses == "trajectory":
        j = int(rng.integers(len(scene.sensor.poses)))
        p = scene.sensor.poses[j]
        pose = {
            "position_m": p.position_m.tolist(),
            "yaw_rad": p.yaw_rad,
            "pitch_rad": p.pitch_rad,
            "roll_rad": p.roll_rad,
            "trajectory_index": j,
        }
    else:
        reg = choice.region
        for _attempt in range(100):
            pos = np.array([rng.uniform(*reg[a]) for a in ("x", "y", "z")])
            if _clear(str(choice.file), pos, choice.clearance_m):
                break
        else:
            raise RuntimeError(
                f"sample {i}: no collision-free pose in the region of {choice.file} after 100 draws"
            )
        yaw = np.deg2rad(rng.uniform(*reg.get("yaw_deg", (0.0, 0.0))))
        pose = {
            "position_m": pos.tolist(),
            "yaw_rad": float(yaw),
            "pitch_rad": 0.0,
            "roll_rad": 0.0,
        }
    cond = {
        name: d.draw(rng)
        for name, d in sorted(spec.randomize.items())
        if name not in ("mount_jitter_deg", "mount_jitter_m")
    }
    if "mount_jitter_deg" in spec.randomize:  # the sensor's mounting: yaw and pitch
        cond["mount_yaw_deg"] = spec.randomize["mount_jitter_deg"].draw(rng)
        cond["mount_pitch_deg"] = spec.randomize["mount_jitter_deg"].draw(rng)
        pose["yaw_rad"] += float(np.deg2rad(cond["mount_yaw_deg"]))
        pose["pitch_rad"] += float(np.deg2rad(cond["mount_pitch_deg"]))
    if "mount_jitter_m" in spec.randomize:
        shift = [spec.randomize["mount_jitter_m"].draw(rng) for _ in range(3)]
        cond["mount_shift_m"] = shift
        pose["position_m"] = (np.asarray(pose["position_m"]) + shift).tolist()
    return {
        "index": i,
        "scene": str(choice.file),
        "pose": pose,
        "conditions": cond,
        "noise_seed": int(rng.integers(2**62)),
    }


def _varied_scene(params: dict):
    from acousim.scene.model import Environment

    scene = _scene(params["scene"])
    c = params["conditions"]
    env = Environment(
        c.get("temperature_c", scene.environment.temperature_c),
        c.get("humidity_percent", scene.environment.humidity_percent),
        scene.environment.pressure_kpa,
    )
    sim = dataclasses.replace(
        scene.simulation, seed=params["noise_seed"], snr_db=c.get("snr_db", scene.simulation.snr_db)
    )
    meshes = scene.meshes
    if "reflection_scale" in c:
        s = min(
            max(c["reflection_scale"], 0.0),
            1.0 / max([m.material.reflection for m in meshes] or [1.0]),
        )
        meshes = tuple(
            dataclasses.replace(
                m, material=dataclasses.replace(m.material, reflection=m.material.reflection * s)
            )
            for m in meshes
        )
    return dataclasses.replace(scene, environment=env, simulation=sim, meshes=meshes)


def make_sample(spec: DatasetSpec, i: int) -> tuple[dict, dict]:
    """(arrays, parameters) of sample i."""
    from acousim.scene import Pose
    from acousim.simulator import Simulator

    params = sample_parameters(spec, i)
    scene = _varied_scene(params)
    p = params["pose"]
    pose = Pose(p["position_m"], p["yaw_rad"], p["pitch_rad"], p["roll_rad"])
    sim = Simulator(scene, threads=1)
    rec = sim.simulate_pose(pose, 0, motion=_motion(pose, params["conditions"]))
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
    if st.snapshot:
        arrays["snapshot"] = snap.data.astype(np.complex64)
        arrays["range_m"] = snap.range_m.astype(np.float32)
    if st.images:
        images = P.acoustic_images(rec, st.images, settings, snapshot=snap)
        for m, img in images.items():
            arrays[f"image/{m}"] = img.db(floor_db=-60).astype(np.float16)
        arrays["range_m"] = snap.range_m.astype(np.float32)
    if st.labels:
        truth = rec.metadata["truth"]
        arrays["labels/position_sensor_m"] = np.asarray(
            truth["position_sensor_m"], np.float32
        ).reshape(-1, 3)
        arrays["labels/amplitude"] = np.asarray(truth["amplitude"], np.float32)
        arrays["labels/order"] = np.asarray(truth["order"], np.int8)
    if st.depth_map:
        arrays["labels/depth_m"] = _depth_map(params["scene"], pose, grid, scene)
    return arrays, params


def _motion(pose, conditions: dict):
    """The sensor driving forward (along its axis) at ``speed_m_s`` and turning about
    the vertical at ``turn_rate_deg_s`` during the measurement, when the spec
    randomises them; None (a frozen pose) otherwise."""
    from acousim.scene.trajectory import Trajectory

    speed = conditions.get("speed_m_s", 0.0)
    turn = conditions.get("turn_rate_deg_s", 0.0)
    if speed == 0 and turn == 0:
        return None
    return Trajectory.constant(pose, speed * pose.rotation[:, 0], [0, 0, np.deg2rad(turn)])


def _depth_map(scene_file: str, pose, grid: P.Grid, scene) -> np.ndarray:
    """Distance to the nearest surface along each grid direction (E, A), inf: none."""
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
    tmp = out / f".{shard_name(k)}.{os.getpid()}.part"
    records = []
    t0 = time.perf_counter()
    try:
        with h5py.File(tmp, "w", track_order=True, libver="latest") as f:
            f.attrs["spec_sha256"] = np.bytes_(spec.sha256)
            for i in range(lo, hi):
                arrays, params = make_sample(spec, i)
                g = _group(f, f"{i - lo:05d}")
                for name, a in arrays.items():
                    *parents, leaf = name.split("/")
                    parent = g
                    for p in parents:
                        parent = parent[p] if p in parent else _group(parent, p)
                    ds = parent.create_dataset(
                        leaf,
                        data=a,
                        compression=spec.compression if a.size > 64 else None,
                        track_times=False,
                    )
                    # write its chunks now, so that file space is allocated in creation
                    # order: left to garbage collection, the chunk cache is flushed when
                    # the last reference goes, later when something (Dask's profiler
                    # sampling this frame) holds one, and the bytes differ
                    ds.flush()
                # fixed-length bytes: no global heap, whose layout varies between processes
                g.attrs["params"] = np.bytes_(json.dumps(params, sort_keys=True))
                records.append({**params, "shard": k, "offset": i - lo})
        digest = hashlib.sha256(tmp.read_bytes()).hexdigest()
        os.replace(tmp, final)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    side = {
        "shard": k,
        "file": final.name,
        "sha256": digest,
        "samples": records,
        "seconds": time.perf_counter() - t0,
        "bytes": final.stat().st_size,
    }
    side_tmp = out / f".{final.stem}.json.part"
    side_tmp.write_text(json.dumps(side, sort_keys=True))
    os.replace(side_tmp, out / f"{final.stem}.json")
    return side


def _shard_job(args: tuple[str, int, str]) -> dict:
    """One shard, with BLAS on one thread: the summation order (and so every bit of
    the result) must not depend on the worker's thread settings (Dask's workers run
    single-threaded BLAS, a local process may not)."""
    from threadpoolctl import threadpool_limits

    spec_path, k, out = args
    with threadpool_limits(1):
        return write_shard(load_spec(spec_path), k, out)


def _done(spec: DatasetSpec, out: Path) -> set[int]:
    done = set()
    for k in range(spec.n_shards):
        if (out / shard_name(k)).is_file() and (out / f"shard_{k:05d}.json").is_file():
            done.add(k)
    return done


def generate(
    spec_path: str | Path,
    out_dir: str | Path,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict:
    """Generate (or finish) a dataset; returns the manifest."""
    spec = load_spec(spec_path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for stale in out.glob(".shard_*.part"):
        stale.unlink()  # an interrupted run's incomplete shard: redone
    existing = out / "spec.sha256"
    if existing.is_file() and existing.read_text().strip() != spec.sha256:
        raise ValueError(
            f"{out} holds a dataset of another spec (sha256 "
            f"{existing.read_text().strip()[:12]}...); use a new folder"
        )
    existing.write_text(spec.sha256 + "\n")
    todo = [k for k in range(spec.n_shards) if k not in _done(spec, out)]
    jobs = [(str(Path(spec_path).resolve()), k, str(out.resolve())) for k in todo]
    done_count = spec.n_shards - len(todo)
    t0 = time.perf_counter()
    if progress:
        progress(done_count, spec.n_shards)
    if scheduler:
        from dask.distributed import Client, as_completed

        with Client(scheduler) as client:
            futures = client.map(_shard_job, jobs, pure=False)
            for _ in as_completed(futures):
                done_count += 1
                if progress:
                    progress(done_count, spec.n_shards)
            client.gather(futures)
    elif workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers) as pool:
            for _ in pool.map(_shard_job, jobs):
                done_count += 1
                if progress:
                    progress(done_count, spec.n_shards)
    else:
        for job in jobs:
            _shard_job(job)
            done_count += 1
            if progress:
                progress(done_count, spec.n_shards)
    elapsed = time.perf_counter() - t0
    return _manifest(spec, out, elapsed, todo)


def _manifest(spec: DatasetSpec, out: Path, elapsed: float, computed: list[int]) -> dict:
    sides = [json.loads((out / f"shard_{k:05d}.json").read_text()) for k in range(spec.n_shards)]
    samples = [s for side in sides for s in side["samples"]]
    total = sum(s["bytes"] for s in sides)
    manifest = {
        "name": spec.name,
        "spec": Path(spec.source).name,
        "spec_sha256": spec.sha256,
        "samples": len(samples),
        "shard_size": spec.shard_size,
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
    tmp = out / f".{MANIFEST}.part"
    tmp.write_text(json.dumps(manifest, indent=1, sort_keys=True))
    os.replace(tmp, out / MANIFEST)
    made = sum(len(sides[k]["samples"]) for k in computed)
    manifest["summary"] = {
        "bytes_per_sample": total / max(len(samples), 1),
        "seconds": elapsed,
        "samples_computed": made,
        "samples_per_second": made / elapsed if elapsed > 0 else 0.0,
    }
    return manifest
