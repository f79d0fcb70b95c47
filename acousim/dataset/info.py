"""What a file holds, in a few lines: a recording file, a dataset shard or a dataset
folder (used by ``acousim info``)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py

import processing as P
from processing.errors import InputError

from .generation import SHARD_SCHEMA

__all__ = ["describe"]


def describe(path: str | Path) -> list[str]:
    """Lines describing `path`; raises InputError for what none of the three is."""
    path = Path(path)
    if path.is_dir():
        return _folder(path)
    if not path.is_file():
        raise InputError("no such file or folder", file=path)
    try:
        with h5py.File(path, "r") as f:
            schema = f.attrs.get("schema")
    except OSError as exc:
        raise InputError(f"not an HDF5 file ({exc})", file=path) from None
    if isinstance(schema, bytes) and schema.decode(errors="replace") == SHARD_SCHEMA:
        return _shard(path)
    return _recordings(path)


def _chirp(path: Path) -> list[str]:
    """A CHIRP file's header: version, captures and sensors."""
    with h5py.File(path, "r") as f:
        sensors = f.get("sensors", {})
        kinds = [f"{k} ({sensors[k].attrs.get('sensor_type', '?')})" for k in sensors]
        return [
            f"{path}: CHIRP file, format {f.attrs.get('format_version', '?')}, "
            f"{f.attrs.get('n_reference_captures', '?')} capture(s); sensors: "
            + (", ".join(kinds) or "none")
            + ("; acousim group (ground truth, metadata)" if "acousim" in f else "")
        ]


def _recordings(path: Path) -> list[str]:
    n = P.count_recordings(path)
    lines = _chirp(path) if P.is_chirp(path) else []
    lines.append(f"{path}: {n} recording(s)")
    for i in range(n):
        try:
            r = P.load_recording(path, i)
        except P.RecordingFileError as exc:
            if not P.is_chirp(path):
                raise
            return [*lines, f"  its recordings cannot be read: {exc.reason} ({exc.key})"]
        kind = "simulated" if r.metadata.get("simulated") else "real"
        where = ""
        p = P.pose_of(r.metadata)
        if p:
            yaw = p["yaw_deg"]
            where = f", pose {[round(v, 3) for v in p['position_m']]} yaw {yaw:.1f}°"
        truth = "" if r.truth is None else f", {len(r.truth)} true paths"
        if r.lidar is not None:
            truth += f", LiDAR {r.lidar.name} scan of {len(r.lidar)} points"
        lines.append(
            f"  [{i}] {kind}, array {r.array.name} ({r.array.n_mics} mics), "
            f"{r.n_measurements} measurement(s) x {r.n_samples} samples at "
            f"{r.sample_rate_hz / 1e3:g} kHz, call {r.waveform.kind} "
            f"{r.waveform.f_start_hz / 1e3:g}->{r.waveform.f_end_hz / 1e3:g} kHz, "
            f"c = {r.speed_of_sound_m_s:.1f} m/s{where}{truth}"
        )
    return lines


def _shard(path: Path) -> list[str]:
    with h5py.File(path, "r") as f:
        samples = sorted(k for k in f if k.isdigit())
        lines = [f"{path}: dataset shard, {len(samples)} sample(s)"]
        if "axes" in f:
            az, el = f["axes/azimuth_deg"][()], f["axes/elevation_deg"][()]
            lines.append(
                f"  image grid: azimuth {az[0]:g}..{az[-1]:g}° ({az.size}), "
                f"elevation {el[0]:g}..{el[-1]:g}° ({el.size})"
            )
        for name in samples:
            g = f[name]
            try:
                params = json.loads(g.attrs["params"])
            except (KeyError, ValueError) as exc:
                raise InputError(f"malformed params ({exc!r})", file=path, key=name) from None
            fields = [f"{k} {d.shape}" for k, d in _datasets(g)]
            pose = params.get("pose", {})
            lines.append(
                f"  [{params.get('index')}] {params.get('scene')}, pose "
                f"{[round(v, 3) for v in pose.get('position_m', [])]} yaw "
                f"{pose.get('yaw_deg', 0.0):.1f}°: {', '.join(fields)}"
            )
    return lines


def _datasets(g: h5py.Group) -> list[tuple[str, h5py.Dataset]]:
    found: list[tuple[str, h5py.Dataset]] = []
    g.visititems(lambda k, o: found.append((k, o)) if isinstance(o, h5py.Dataset) else None)
    return found


def _folder(path: Path) -> list[str]:
    from .reader import DatasetReader

    reader = DatasetReader(path, verify=False)
    m = reader.manifest
    total = sum(s["bytes"] for s in m["shards"])
    lines = [
        f"{path}: dataset {m.get('name')!r}, {m['samples']} sample(s) in "
        f"{len(m['shards'])} shard(s), {total / 1e6:.1f} MB, spec {m.get('spec')} "
        f"(sha256 {str(m.get('spec_sha256'))[:12]}...)"
    ]
    for s in m["shards"]:
        lines.append(f"  {s['file']}: {s['samples']} sample(s), {s['bytes'] / 1e6:.2f} MB")
    return lines
