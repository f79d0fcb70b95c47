"""Reading and validating the HDF5 recording file (schema in :mod:`processing.formats.native`
and ``docs/recording-format.md``): every field checked, a problem raised as
:class:`RecordingFileError` naming the file and field."""

from __future__ import annotations

import hashlib
import json
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from processing.base.errors import InputError
from processing.formats.h5attrs import attribute_text
from processing.sensor.arrays import Array
from processing.sensor.calibration import on_load
from processing.sensor.calls import Waveform
from processing.sensor.metadata import metadata_problem
from processing.sensor.pointcloud import read_point_cloud
from processing.sensor.provenance import Provenance
from processing.sensor.recording import (
    SCHEMA,
    STORED_SEEN,
    SUPPORTED_VERSIONS,
    GroundTruth,
    Recording,
    RecordingFileError,
    check_waveform,
    with_last_points,
)


def lidar_group(n: int) -> str:
    """The group of a recording's LiDAR scan n: ``lidar`` (the first), then a rig's
    other LiDARs' ``lidar_01``, ``lidar_02``, ..."""
    return "lidar" if n == 0 else f"lidar_{n:02d}"


def lidar_groups(g: h5py.Group) -> list[str]:
    """The LiDAR scan groups of recording group `g`, in order (they run on without a
    gap from ``lidar``)."""
    out = []
    while lidar_group(len(out)) in g:
        out.append(lidar_group(len(out)))
    return out


def read_all(path: Path, max_bytes: int) -> list[Recording]:
    """Every recording of an HDF5 recording file, in order."""
    with _open(path) as (f, version, names):
        return [_read_one(path, f["recordings"][n], version, max_bytes) for n in names]


def read_index(path: Path, index: int, max_bytes: int) -> Recording:
    """Recording `index` (negative: from the end) of an HDF5 recording file."""
    with _open(path) as (f, version, names):
        if not -len(names) <= index < len(names):
            raise RecordingFileError(
                f"index out of range ({len(names)} recordings)", file=path, key="index", value=index
            )
        return _read_one(path, f["recordings"][names[index]], version, max_bytes)


def count(path: Path) -> int:
    """How many recordings an HDF5 recording file holds (without reading them)."""
    with _open(path) as (_, _, names):
        return len(names)


def _sha256(samples: np.ndarray) -> str:
    """sha256 of the samples as little-endian numbers in C order (as stored)."""
    x = np.ascontiguousarray(samples, samples.dtype.newbyteorder("<"))
    return hashlib.sha256(x.data).hexdigest()


@contextmanager
def _open(path: Path):
    if not path.is_file():
        raise RecordingFileError("no such file", file=path)
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise RecordingFileError(f"not an HDF5 file ({exc})", file=path) from None
    try:
        with f:
            version, names = _checked(path, f)
            yield f, version, names
    except (OSError, RuntimeError, KeyError) as exc:
        # what h5py raises when HDF5 cannot parse a structure (object header, B-tree,
        # heap) of a damaged file; our own checks raise RecordingFileError
        raise RecordingFileError(f"damaged HDF5 structure ({exc})", file=path) from None


def _checked(path: Path, f: h5py.File) -> tuple[int, list[str]]:
    """(schema version, group names in order) of a file whose root is valid."""
    schema = _text(f.attrs.get("schema"))
    if schema != SCHEMA:
        raise RecordingFileError(
            f"not a recording file (expected {SCHEMA!r})",
            file=path,
            key="schema",
            value=_plain(f.attrs.get("schema")),
        )
    raw = f.attrs.get("schema_version")
    if not (isinstance(raw, (int, np.integer)) and int(raw) in SUPPORTED_VERSIONS):
        raise RecordingFileError(
            f"unsupported; this version reads {SUPPORTED_VERSIONS}",
            file=path,
            key="schema_version",
            value=_plain(raw),
        )
    if "recordings" not in f or not isinstance(f["recordings"], h5py.Group):
        raise RecordingFileError("missing group", file=path, key="recordings")
    names = list(f["recordings"].keys())
    bad = [n for n in names if not n.isdigit()]
    if bad:
        raise RecordingFileError(
            "group names must be numbers", file=path, key="recordings", value=bad[0]
        )
    count = f.attrs.get("count", len(names))  # schema 2 records it
    if not (isinstance(count, (int, np.integer)) and int(count) == len(names)):
        raise RecordingFileError(
            f"the file holds {len(names)} recording group(s) (damaged or edited?)",
            file=path,
            key="count",
            value=_plain(count),
        )
    return int(raw), sorted(names, key=int)


def _plain(value):
    """A value as shown in an error: numpy scalars and arrays as Python ones."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


_text = attribute_text  # the one reading of a text attribute


def _dataset(
    path: Path, g: h5py.Group, name: str, ndim: tuple[int, ...], kind: str, units: str | None = None
) -> h5py.Dataset:
    key = f"{g.name}/{name}"
    try:
        d = g[name]  # one look-up (a test of membership first costs as much again)
    except KeyError:
        d = None
    if not isinstance(d, h5py.Dataset):
        raise RecordingFileError("missing", file=path, key=key)
    if d.ndim not in ndim:
        raise RecordingFileError(
            f"expected {' or '.join(map(str, ndim))} dimensions", file=path, key=key, value=d.shape
        )
    if d.dtype.kind not in kind:
        raise RecordingFileError(
            f"dtype not allowed (kinds {kind!r})", file=path, key=key, value=str(d.dtype)
        )
    if units is not None and _text(d.attrs.get("units")) != units:
        raise RecordingFileError(
            f"units expected {units!r}", file=path, key=f"{key}.units", value=d.attrs.get("units")
        )
    _check_filters(path, d, key)
    return d


def _check_filters(path: Path, d: h5py.Dataset, key: str) -> None:
    plist = d.id.get_create_plist()
    for i in range(plist.get_nfilters()):
        code, _flags, _values, name = plist.get_filter(i)
        if not h5py.h5z.filter_avail(code):
            label = name.decode(errors="replace") if isinstance(name, bytes) else str(name)
            raise RecordingFileError(
                "compression filter not available in this HDF5 installation",
                file=path,
                key=f"{key} filter",
                value=f"{code} {label}".strip(),
            )


def _read(path: Path, d: h5py.Dataset, key: str) -> np.ndarray:
    try:
        return d[()]
    except OSError as exc:
        raise RecordingFileError(
            f"cannot be read: corrupted or checksum mismatch ({exc})", file=path, key=key
        ) from None


def _attr(path: Path, g: h5py.Group, name: str, kind: type = float):
    key = f"{g.name}.{name}"
    if name not in g.attrs:
        raise RecordingFileError("missing attribute", file=path, key=key)
    v = g.attrs[name]
    if kind is str:
        text = _text(v)
        if text is None:
            raise RecordingFileError("must be a string", file=path, key=key, value=_plain(v))
        return text
    ok = np.ndim(v) == 0 and isinstance(v, (int, float, np.integer, np.floating))
    if kind is int:
        ok = ok and float(v) == int(v)
    if not ok or not np.isfinite(float(v)):
        raise RecordingFileError(
            f"must be a finite {kind.__name__}", file=path, key=key, value=_plain(v)
        )
    return kind(v)


def _samples(path: Path, g: h5py.Group, max_bytes: int) -> np.ndarray:
    key = f"{g.name}/samples"
    d = _dataset(path, g, "samples", (2, 3), "f", "1")
    declared = int(np.prod(d.shape, dtype=np.float64)) * d.dtype.itemsize
    if declared > max_bytes:
        raise RecordingFileError(
            f"declares {declared / 2**30:,.0f} GiB of samples, more than the limit "
            f"max_bytes = {max_bytes / 2**30:.3g} GiB",
            file=path,
            key=key,
            value=d.shape,
        )
    if declared and d.id.get_storage_size() == 0:
        raise RecordingFileError("declares samples but stores none", file=path, key=key)
    x = _read(path, d, key)
    if not np.all(np.isfinite(x)):
        n = int(np.size(x) - np.count_nonzero(np.isfinite(x)))
        raise RecordingFileError(f"{n} samples are NaN or infinite", file=path, key=key)
    if "sha256" in d.attrs and _text(d.attrs["sha256"]) != _sha256(x):
        raise RecordingFileError(
            "samples differ from the checksum written with them (corrupted file)",
            file=path,
            key=f"{key}.sha256",
        )
    return x


def _array(path: Path, g: h5py.Group) -> Array:
    pos = _read(path, _dataset(path, g, "array/positions", (2,), "f", "m"), "array/positions")
    emitter = _read(path, _dataset(path, g, "array/emitter", (1,), "f", "m"), "array/emitter")
    channels = _read(path, _dataset(path, g, "array/channels", (1,), "iu"), "array/channels")
    key = f"{g.name}/array/positions"
    if pos.ndim != 2 or pos.shape[1] != 3 or not np.all(np.isfinite(pos)):
        raise RecordingFileError(
            "must be finite (M, 3) metres", file=path, key=key, value=pos.shape
        )
    if len(np.unique(pos, axis=0)) < len(pos):
        raise RecordingFileError("two microphones at the same position", file=path, key=key)
    if emitter.shape != (3,) or not np.all(np.isfinite(emitter)):
        raise RecordingFileError(
            "must be 3 finite metres",
            file=path,
            key=f"{g.name}/array/emitter",
            value=_plain(emitter),
        )
    grid_index = pitch = None
    if "array/grid_index" in g:
        d = _dataset(path, g, "array/grid_index", (2,), "iu")
        grid_index = _read(path, d, "array/grid_index")
        key = f"{g.name}/array/grid_index.pitch_m"
        if "pitch_m" not in d.attrs:
            raise RecordingFileError("missing attribute", file=path, key=key)
        pitch = np.asarray(d.attrs["pitch_m"])
        if (
            pitch.shape != (2,)
            or pitch.dtype.kind not in "fiu"
            or not np.all(np.isfinite(pitch))
            or not np.all(pitch > 0)
        ):
            raise RecordingFileError(
                "must be two positive finite metres (dz, dy)",
                file=path,
                key=key,
                value=_plain(pitch),
            )
        pitch = (float(pitch[0]), float(pitch[1]))
    name = _attr(path, g, "array_name", str)
    try:
        return Array(name, pos, emitter, grid_index, pitch, channels)
    except ValueError as exc:
        raise RecordingFileError(str(exc), file=path, key=f"{g.name}/array") from None


def _waveform(path: Path, g: h5py.Group, sample_rate_hz: float) -> Waveform:
    key = f"{g.name}.waveform"
    text = _attr(path, g, "waveform", str)
    try:
        w = Waveform.from_dict(json.loads(text))
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        raise RecordingFileError(f"not a waveform ({exc})", file=path, key=key) from None
    _check_waveform(path, key, w, sample_rate_hz)
    return w


def _check_waveform(path: Path, key: str, w: Waveform, sample_rate_hz: float) -> None:
    check_waveform(w, sample_rate_hz, file=path, key=key, error=RecordingFileError)


def _metadata(path: Path, g: h5py.Group) -> dict:
    key = f"{g.name}/metadata"
    if "metadata" not in g or not isinstance(g["metadata"], h5py.Dataset):
        raise RecordingFileError("missing", file=path, key=key)
    raw = _read(path, g["metadata"], key)
    try:
        meta = json.loads(raw.decode() if isinstance(raw, bytes) else raw)
    except (ValueError, TypeError, AttributeError) as exc:
        raise RecordingFileError(f"not JSON ({exc})", file=path, key=key) from None
    _check_metadata(path, key, meta)
    try:
        Provenance.from_metadata(meta, file=path, key=key)
    except InputError as exc:
        raise RecordingFileError(exc.reason, file=path, key=exc.key, value=exc.value) from None
    return meta


def _check_metadata(path: Path, key: str, meta) -> None:
    """The metadata keys the programs read, each checked (processing.sensor.metadata)."""
    problem = metadata_problem(meta)
    if problem is not None:
        sub, reason, value = problem
        raise RecordingFileError(reason, file=path, key=f"{key}{sub}", value=value)


def _truth(path: Path, g: h5py.Group) -> GroundTruth | None:
    if "truth" not in g:
        return None
    key = f"{g.name}/truth"
    t = g["truth"]
    if not isinstance(t, h5py.Group):
        raise RecordingFileError("must be a group", file=path, key=key)
    fields = {}
    for name, ndim, kind, units in (
        ("position_world_m", (2,), "f", "m"),
        ("position_sensor_m", (2,), "f", "m"),
        ("amplitude", (1,), "f", "1"),
        ("order", (1,), "iu", "1"),
        ("kind", (1,), "S", None),
    ):
        fields[name] = _read(path, _dataset(path, t, name, ndim, kind, units), f"{key}/{name}")
    fields["kind"] = _ascii(fields["kind"])
    if "velocity_world_m_s" in t:  # scenes with motion
        name = "velocity_world_m_s"
        ds = _dataset(path, t, name, (2,), "f", "m/s")
        fields[name] = _read(path, ds, f"{key}/{name}")
    if "emitter" in t:  # a rig's recording: the sonar each path's call came from
        ds = _dataset(path, t, "emitter", (1,), "S", None)
        fields["emitter"] = np.char.decode(_read(path, ds, f"{key}/emitter"), "utf-8")
    fields.update(_seen(path, t, key))
    try:
        return GroundTruth(**with_last_points(fields))
    except ValueError as exc:
        raise RecordingFileError(str(exc), file=path, key=key) from None


def _ascii(names: np.ndarray) -> np.ndarray:
    """Byte strings (N,) as str: numpy's cast when every byte is ASCII (a hundred
    times faster than decoding each), else decoded with U+FFFD for the others."""
    if names.dtype.itemsize and np.any(names.reshape(-1).view(np.uint8) >= 128):
        return np.char.decode(names, "ascii", errors="replace")
    return names.astype(f"U{max(names.dtype.itemsize, 1)}")


def _seen(path: Path, t: h5py.Group, key: str) -> dict:
    """The fields of what the sensor sees, those the file has (a file written before
    they existed has none: the truth reads as it did)."""
    out = {}
    for name, units in STORED_SEEN.items():
        if name in t:
            ndim, kind = ((1,), "iu") if name in ("delay_s", "object_index") else ((2,), "f")
            kind = "f" if name == "delay_s" else kind
            out[name] = _read(path, _dataset(path, t, name, ndim, kind, units), f"{key}/{name}")
    if "object_names" in t:
        ds = _dataset(path, t, "object_names", (1,), "SO")
        out["object_names"] = tuple(_text(x) or "" for x in _read(path, ds, f"{key}/object_names"))
    return out


def _truth_v1(path: Path, g: h5py.Group, meta: dict) -> GroundTruth | None:
    """Schema 1 kept the ground truth as a JSON object in the metadata."""
    t = meta.pop("truth", None)
    if t is None:
        return None
    key = f"{g.name}/metadata: truth"
    try:
        return GroundTruth(
            t["position_world_m"],
            t["position_sensor_m"],
            t["amplitude"],
            t["order"],
            t["kind"],
            t.get("velocity_world_m_s"),
        )
    except (ValueError, TypeError, KeyError) as exc:
        raise RecordingFileError(f"malformed ({exc!r})", file=path, key=key) from None


def _read_one(path: Path, g: h5py.Group, version: int, max_bytes: int) -> Recording:
    if not isinstance(g, h5py.Group):
        raise RecordingFileError("must be a group", file=path, key=g.name)
    samples = _samples(path, g, max_bytes)
    fs = _attr(path, g, "sample_rate_hz")
    array = _array(path, g)
    waveform = _waveform(path, g, fs)
    meta = _metadata(path, g)
    truth = _truth(path, g) if version >= 2 else _truth_v1(path, g, meta)
    scans = [read_point_cloud(path, g[name], RecordingFileError) for name in lidar_groups(g)]
    try:
        rec = Recording(
            samples=samples,
            sample_rate_hz=fs,
            array=array,
            waveform=waveform,
            speed_of_sound_m_s=_attr(path, g, "speed_of_sound_m_s"),
            emission_index=_attr(path, g, "emission_index", int),
            metadata=meta,
            truth=truth,
            lidar=scans[0] if scans else None,
            other_lidars=tuple(scans[1:]),
        )
    except (ValueError, TypeError) as exc:
        if isinstance(exc, RecordingFileError):
            raise
        raise RecordingFileError(str(exc), file=path, key=g.name) from None
    return on_load(rec, path)  # a stored array calibration, applied once
