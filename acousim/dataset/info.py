"""What a file holds, in a few lines: a recording file, a dataset shard, a dataset
folder, an image file (``images.h5``), a folder of ``acousim image`` (its pictures,
peaks.csv and images.h5) or a ROS 2 bag folder: everything acousim writes (used by
``acousim info``)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import h5py
import numpy as np

import processing as P
from acousim.dataset.generation import MANIFEST, SHARD_SCHEMA
from acousim.dataset.reader import DatasetReader
from processing.base.errors import InputError
from processing.formats.h5attrs import attribute_text
from processing.sensor.provenance import kind_of

IMAGES_FORMAT = "acousim-images"  # acousim.export.images.FORMAT (not imported: light)

__all__ = ["describe"]


def describe(path: str | Path) -> list[str]:
    """Lines describing `path`; raises InputError for what acousim does not write."""
    path = Path(path)
    if path.is_dir():  # a ROS 2 bag, an image folder, else a dataset (the reader
        if (path / "metadata.yaml").is_file():  # names what is missing)
            return _bag(path)
        if not (path / MANIFEST).is_file() and not any(path.glob("shard_*.h5")):
            if _is_image_folder(path):
                return _image_folder(path)
            raise InputError(
                f"not a folder acousim writes: no {MANIFEST} (a dataset; or its generation "
                f"is unfinished), no {PEAKS_CSV}, {IMAGES_H5} or fan.png (acousim image's "
                "pictures), no metadata.yaml (a ROS 2 bag)",
                file=path,
            )
        return _folder(path)
    if not path.is_file():
        raise InputError("no such file or folder", file=path)
    try:
        with h5py.File(path, "r") as f:
            schema, fmt = f.attrs.get("schema"), f.attrs.get("format")
    except OSError as exc:
        raise InputError(f"not an HDF5 file ({exc})", file=path) from None
    if _text(schema) == SHARD_SCHEMA:
        return _shard(path)
    if _text(fmt) == IMAGES_FORMAT:
        return _images(path)
    return _recordings(path)


_text = attribute_text  # the one reading of a text attribute: None for an array


def _images(path: Path) -> list[str]:
    """An images.h5 (acousim.export.images): one line per imaged recording."""
    with h5py.File(path, "r") as f:
        groups = sorted(k for k in f if isinstance(f[k], h5py.Group))
        lines = [f"{path}: images of {len(groups)} recording(s) (format {IMAGES_FORMAT})"]
        for name in groups:
            g = f[name]
            methods = [k for k in g if _text(g[k].attrs.get("units")) == "dB"]  # the images
            shape = g[methods[0]].shape if methods else ()
            r = g["range_m"][()] if "range_m" in g else np.empty(0)
            span = f", range {r[0]:.2f}..{r[-1]:.2f} m" if r.size else ""
            kind = _text(g.attrs.get("provenance", "")) or "unknown provenance"
            scene = _text(g.attrs.get("scene", ""))
            lines.append(
                f"  [{g.attrs.get('index', name)}] {kind}{f' ({scene})' if scene else ''}: "
                f"{', '.join(methods)} (range x elevation x azimuth {shape}{span})"
            )
    return lines


#: what ``acousim image`` writes in its folder besides the pictures
PEAKS_CSV, IMAGES_H5 = "peaks.csv", "images.h5"
#: the pictures' extensions (fan, elaz_METHOD, scene3d: PNG; the drive: GIF)
PICTURES = (".png", ".gif")


def _is_image_folder(path: Path) -> bool:
    """Whether `path` (a folder without manifest.json) looks written by ``acousim
    image``: its peaks.csv or images.h5, or its fan picture."""
    return any((path / name).is_file() for name in (PEAKS_CSV, IMAGES_H5)) or any(
        path.glob("fan*.png")
    )


def _image_folder(path: Path) -> list[str]:
    """A folder written by ``acousim image``: its pictures, peaks.csv (its rows) and
    images.h5 (described as :func:`_images` does)."""
    pictures = sorted(p.name for p in path.iterdir() if p.suffix.lower() in PICTURES)
    lines = [
        f"{path}: a folder written by acousim image: {len(pictures)} picture(s)"
        + (f" ({', '.join(pictures)})" if pictures else "")
    ]
    if (path / PEAKS_CSV).is_file():
        lines.append(f"  {PEAKS_CSV}: {_peaks_summary(path / PEAKS_CSV)}")
    if (path / IMAGES_H5).is_file():
        lines += ["  " + line for line in _images(path / IMAGES_H5)]
    else:
        lines.append(f"  no {IMAGES_H5} (acousim image --images-h5 writes the images as data)")
    return lines


def _peaks_summary(path: Path) -> str:
    """peaks.csv in a few words: its rows, recordings and methods."""
    with path.open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    recordings = {r.get("recording") for r in rows}
    methods = sorted({r.get("method") or "?" for r in rows})
    return (
        f"{len(rows)} peak row(s) of {len(recordings)} recording(s), "
        f"method(s) {', '.join(methods) or 'none'}"
    )


def _bag(path: Path) -> list[str]:
    """A ROS 2 bag folder (acousim.export.rosbag): topics, counts, provenance."""
    try:
        from rosbags.rosbag2 import Reader, ReaderError
    except ImportError:
        raise InputError(
            "a ROS 2 bag; reading it needs rosbags (pip install 'acousim[ros]')", file=path
        ) from None
    try:
        reader = Reader(path)
        reader.open()
    except ReaderError as exc:  # a damaged or foreign bag
        raise InputError(f"not a readable ROS 2 bag ({exc})", file=path) from None
    try:
        span = (reader.end_time - reader.start_time) / 1e9 if reader.message_count else 0.0
        lines = [
            f"{path}: ROS 2 bag ({', '.join(sorted(p.name for p in path.glob('*.mcap')))}), "
            f"{reader.message_count} message(s) over {span:.2f} s"
        ]
        info = [c for c in reader.connections if _is_info_topic(c.topic)]  # a rig: per sonar
        kinds: dict[str, int] = {}
        for _, _, raw in reader.messages(connections=info) if info else ():  # [] reads all
            kind = _bag_provenance(raw)
            kinds[kind] = kinds.get(kind, 0) + 1
        if kinds:
            lines.append("  recordings: " + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())))
        for c in sorted(reader.connections, key=lambda c: c.topic):
            lines.append(f"  {c.topic}: {c.msgtype}, {c.msgcount} message(s)")
    finally:
        reader.close()
    return lines


def _is_info_topic(topic: str) -> bool:
    """``/acousim/info`` or a rig's sonar's ``/acousim/<sonar>/info``."""
    parts = topic.split("/")
    return parts[:2] == ["", "acousim"] and parts[-1] == "info" and len(parts) in (3, 4)


def _bag_provenance(raw: bytes) -> str:
    from rosbags.typesys import Stores, get_typestore

    msg = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(raw, "std_msgs/msg/String")
    try:
        info = json.loads(msg.data)
    except ValueError:
        return "unknown"
    return str(kind_of(info))


def _chirp(path: Path) -> list[str]:
    """A CHIRP file's header: version, captures and sensors."""
    with h5py.File(path, "r") as f:
        sensors = f.get("sensors", {})
        kinds = [f"{k} ({sensors[k].attrs.get('sensor_type', '?')})" for k in sensors]
        rig = f["acousim"].attrs.get("sensors") if "acousim" in f else None
        whose = "" if rig is None else f" of the reference sonar {json.loads(_text(rig))[0]!r}"
        return [
            f"{path}: CHIRP file, format {f.attrs.get('format_version', '?')}, "
            f"{f.attrs.get('n_reference_captures', '?')} capture(s){whose}; sensors: "
            + (", ".join(kinds) or "none")
            + ("; acousim group (ground truth, metadata)" if "acousim" in f else "")
        ]


def _recordings(path: Path) -> list[str]:
    n = P.count_recordings(path)
    lines = _chirp(path) if P.is_chirp(path) else []
    lines.append(f"{path}: {n} recording(s)")
    sonars: dict[str, list] = {}  # a rig's file: each sonar's firings and mount
    for i in range(n):
        try:
            r = P.load_recording(path, i)
        except P.RecordingFileError as exc:
            if not P.is_chirp(path):
                raise
            return [*lines, f"  its recordings cannot be read: {exc.reason} ({exc.key})"]
        prov = r.provenance
        kind = prov.kind + (f" ({prov.scene})" if prov.scene else "")
        where = ""
        if prov.pose is not None:
            p = prov.pose
            yaw, pitch, roll = np.rad2deg([p.yaw_rad, p.pitch_rad, p.roll_rad])
            where = (
                f", pose {[round(v, 3) for v in p.position_m]} "
                f"yaw {yaw:.1f}° pitch {pitch:.1f}° roll {roll:.1f}°"
            )
        truth = "" if r.truth is None else f", {len(r.truth)} true paths"
        sensor = r.metadata.get("sensor")
        if sensor is not None:  # a rig's recording: its sonar and the calls it heard
            heard = sorted({h["sensor"] for h in r.metadata.get("crosstalk", [])})
            kind += f", sonar {sensor!r} fired at {r.metadata.get('emission_time_s', 0):.3f} s"
            truth += f", crosstalk from {', '.join(heard)}" if heard else ", no crosstalk"
            sonars.setdefault(str(sensor), [0, r.metadata.get("mount")])[0] += 1
        if r.lidar is not None:
            truth += f", LiDAR {r.lidar.name} scan of {len(r.lidar)} points"
        lines.append(
            f"  [{i}] {kind}, array {r.array.name} ({r.array.n_mics} mics), "
            f"{r.n_measurements} measurement(s) x {r.n_samples} samples at "
            f"{r.sample_rate_hz / 1e3:g} kHz, call {r.waveform.kind} "
            f"{r.waveform.f_start_hz / 1e3:g}->{r.waveform.f_end_hz / 1e3:g} kHz, "
            f"c = {r.speed_of_sound_m_s:.1f} m/s{where}{truth}"
        )
    if sonars:
        lines.append(f"  a rig of {len(sonars)} sonar(s): " + "; ".join(_sonar(sonars)))
    return lines


def _sonar(sonars: dict[str, list]) -> list[str]:
    """Each sonar of a rig's file: its firings and its mount (m; roll, pitch, yaw °)."""
    out = []
    for name, (count, mount) in sonars.items():
        text = f"{name!r} {count} firing(s)"
        if isinstance(mount, dict):
            pos = [round(float(v), 4) for v in mount.get("position_m", [])]
            rot = [round(float(v), 2) for v in mount.get("rotation_deg", [])]
            text += f", mount {pos} m, roll/pitch/yaw {rot}°"
        out.append(text)
    return out


def _shard(path: Path) -> list[str]:
    with h5py.File(path, "r") as f:
        samples = sorted(k for k in f if k.isdigit())
        lines = [f"{path}: dataset shard, {len(samples)} sample(s)"]
        if "axes" in f:
            az, el = f["axes/azimuth_deg"][()], f["axes/elevation_deg"][()]
            r = f["axes/range_m"][()] if "range_m" in f["axes"] else None
            span = "" if r is None else f", range {r[0]:g}..{r[-1]:g} m ({r.size})"
            lines.append(
                f"  image grid: azimuth {az[0]:g}..{az[-1]:g}° ({az.size}), "
                f"elevation {el[0]:g}..{el[-1]:g}° ({el.size}){span}"
            )
        for name in samples:
            g = f[name]
            try:
                params = json.loads(_text(g.attrs["params"]) or "")  # an array: malformed
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
