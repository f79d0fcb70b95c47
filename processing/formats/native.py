"""The recording container and its HDF5 file format.

Time origin (the one convention of the whole package): sample ``n`` of a recording
is at time ``(n - emission_index) / sample_rate_hz`` after the start of the
emission.  A reflector at range r therefore peaks at ``emission_index + 2 r / c *
fs`` after the matched filter.  Nothing in :mod:`processing` adds any other delay.

The file format (schema version 2; version 1 files still load) is described in
``docs/recording-format.md``::

    /                      attrs: schema="acousim.recordings", schema_version=2, count
    /recordings/000000/    one group per recording, names zero-padded to one width
        samples            (M, T) or (K, M, T) float32, chunked per microphone,
                           fletcher32 checksum, attrs units="1", sha256
        array/positions    (M, 3) float, attrs units="m"
        array/emitter      (3,)   float, attrs units="m"
        array/channels     (M,)   int
        array/grid_index   (M, 2) int   (URA only; attrs pitch_m=(dz, dy))
        truth/...          ground truth (simulations): position_world_m (N, 3),
                           position_sensor_m (N, 3), amplitude (N,), order (N,),
                           kind (N,) ASCII, velocity_world_m_s (N, 3) (scenes with
                           motion only), emitter (N,) UTF-8 (a rig's recordings:
                           the sonar whose call each path carries); what the
                           sensor sees (absent in files
                           written before it existed: read as None): delay_s (N,),
                           arrival_sensor (N, 3), apparent_position_sensor_m and
                           apparent_position_world_m (N, 3), first_point_m (N, 3)
                           (float32; last_point_m is position_world_m, NaN for the
                           direct path: not stored), object_index (N,) int32,
                           object_names (O,) UTF-8 (see docs/recording-format.md)
        lidar/             a LiDAR scan (processing.sensor.pointcloud); a rig's other
        lidar_01/, ...     LiDARs' scans after it
        metadata           scalar string: JSON object (pose, scene, seed, ...)
        attrs: sample_rate_hz, speed_of_sound_m_s, emission_index, array_name,
               waveform (JSON)
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import h5py
import numpy as np
from numpy.typing import DTypeLike

from processing.base.atomic import atomic_path
from processing.base.errors import InputError
from processing.formats import native_schema as recording_schema
from processing.formats.native_schema import _check_metadata, _check_waveform, _sha256, lidar_group
from processing.formats.registry import reader_of
from processing.sensor.calls import Waveform
from processing.sensor.pointcloud import write_point_cloud
from processing.sensor.recording import (  # noqa: F401  (re-exported)
    _KINDS,
    MAX_SAMPLE_BYTES,
    SCHEMA,
    SCHEMA_VERSION,
    STORED_SEEN,
    SUPPORTED_VERSIONS,
    GroundTruth,
    Recording,
    RecordingFileError,
)

__all__ = [
    "Recording",
    "save_recordings",
    "load_recordings",
    "save_recording",
    "load_recording",
    "SCHEMA",
    "SCHEMA_VERSION",
    "RecordingFileError",
    "GroundTruth",
    "count_recordings",
    "MAX_SAMPLE_BYTES",
]

# ---------------------------------------------------------------- writing


def save_recordings(
    path: str | Path,
    recordings: Sequence[Recording],
    *,
    dtype: DTypeLike = np.float32,
    compression: str | None = None,
    checksum: bool = True,
) -> Path:
    """Write recordings to one HDF5 file, atomically (see :mod:`processing.base.atomic`).

    Parameters
    ----------
    dtype : float32 (default) or float64
        Sample type in the file. float32 rounds each sample to 24 significant bits, a
        relative error of at most 2**-24 (6e-8, -144 dB): far below the noise of any
        simulation with a finite SNR, and none at all for the real sensor, whose decoded
        samples are float32 already. float64 keeps simulated samples bit-exact.
    compression : "gzip", "lzf" or None
        h5py filter for the samples; none by default: recorded noise does not compress
        (gzip saves about 4 % of a noisy recording), a noise-free simulation does.
    checksum : bool
        Default on: HDF5's fletcher32 checksum on every chunk of the samples and the
        ground truth, and the sha256 of the samples as their attribute ``sha256``
        (which also catches a chunk HDF5 can no longer find and would read as zeros).
        A corrupted file then fails to load instead of loading wrong numbers.
    """
    path = Path(path)
    dtype = np.dtype(dtype)
    if dtype not in (np.float32, np.float64):
        raise ValueError(f"dtype must be float32 or float64, got {dtype}")
    for i, rec in enumerate(recordings):  # what the reader would refuse is never written
        _check_for_writing(path, i, rec)
        big = float(np.max(np.abs(rec.samples), initial=0.0))
        if big > np.finfo(dtype).max:
            raise InputError(
                f"samples reach {big:.3g}, beyond {dtype} (written as inf, which the reader "
                "refuses); save with dtype=np.float64",
                file=path,
                key=f"recording {i}.samples",
            )
    width = _name_width(len(recordings))
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["schema"] = SCHEMA
        f.attrs["schema_version"] = SCHEMA_VERSION
        f.attrs["count"] = len(recordings)
        group = f.create_group("recordings")
        for i, rec in enumerate(recordings):
            opts = {"dtype": dtype, "compression": compression, "checksum": checksum}
            _write_one(group.create_group(f"{i:0{width}d}"), rec, opts)
    return path


def _check_for_writing(path: Path, i: int, rec: Recording) -> None:
    """The reader's checks before writing: the waveform below Nyquist (the same check
    as the Recording's constructor, here naming the file: a Recording changed in place
    since), the metadata's known keys, JSON-serialisable metadata."""
    where = f"recording {i}"
    if not isinstance(rec, Recording):
        raise InputError("not a Recording", file=path, key=where, value=type(rec).__name__)
    _check_waveform(path, f"{where}.waveform", rec.waveform, rec.sample_rate_hz)
    try:
        text = json.dumps(rec.metadata, default=_json_default, allow_nan=True)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"not JSON-serialisable ({exc})", file=path, key=f"{where}.metadata"
        ) from None
    _check_metadata(path, f"{where}.metadata", json.loads(text))


def _name_width(n: int) -> int:
    """Digits of the group names: zero-padded to one width, so that names sort in order."""
    return max(6, len(str(max(n - 1, 0))))


def _write_one(g: h5py.Group, rec: Recording, opts: dict) -> None:
    samples = np.asarray(rec.samples, opts["dtype"])
    chunks = (1,) * (samples.ndim - 1) + (samples.shape[-1],)  # one microphone's signal
    d = g.create_dataset(
        "samples",
        data=samples,
        chunks=chunks,
        compression=opts["compression"],
        fletcher32=opts["checksum"],
    )
    d.attrs["units"] = "1"
    if opts["checksum"]:
        d.attrs["sha256"] = _sha256(samples)
    a = g.create_group("array")
    a.create_dataset("positions", data=rec.array.positions_m).attrs["units"] = "m"
    a.create_dataset("emitter", data=rec.array.emitter_m).attrs["units"] = "m"
    a.create_dataset("channels", data=rec.array.channels)
    if rec.array.grid_index is not None:
        gi = a.create_dataset("grid_index", data=rec.array.grid_index)
        gi.attrs["pitch_m"] = np.asarray(rec.array.pitch_m)
    g.attrs["array_name"] = rec.array.name
    g.attrs["sample_rate_hz"] = rec.sample_rate_hz
    g.attrs["speed_of_sound_m_s"] = rec.speed_of_sound_m_s
    g.attrs["emission_index"] = rec.emission_index
    g.attrs["waveform"] = json.dumps(rec.waveform.to_dict())
    if rec.truth is not None:
        t = g.create_group("truth")
        kw = {"fletcher32": opts["checksum"]} if len(rec.truth) else {}
        for name, data, units in (
            ("position_world_m", rec.truth.position_world_m, "m"),
            ("position_sensor_m", rec.truth.position_sensor_m, "m"),
            ("amplitude", rec.truth.amplitude, "1"),
            ("order", rec.truth.order.astype(np.int16), "1"),
            ("kind", rec.truth.kind.astype("S16"), None),
            ("velocity_world_m_s", rec.truth.velocity_world_m_s, "m/s"),
            ("emitter", _names(rec.truth.emitter), None),
            *((name, getattr(rec.truth, name), units) for name, units in STORED_SEEN.items()),
        ):
            if data is None:  # no motion, one sonar, a truth without the seen fields
                continue
            data = _narrow(name, data)
            # one chunk per field (h5py's guess splits a (N, 3) field into columns
            # and rows: eight checksummed chunks of a few kB, each written and read)
            chunks = {"chunks": _one_chunk(data)} if kw else {}
            ds = t.create_dataset(name, data=data, **kw, **chunks)
            if units:
                ds.attrs["units"] = units
        if rec.truth.object_index is not None:
            t.create_dataset("object_names", data=list(rec.truth.object_names), dtype=_STR)
    for n, scan in enumerate(rec.lidars):  # a rig's other LiDARs: lidar_01, lidar_02, ...
        write_point_cloud(g.create_group(lidar_group(n)), scan, opts["checksum"])
    # a dataset, not an attribute: it can exceed HDF5's 64 kB attribute limit
    g.create_dataset("metadata", data=json.dumps(rec.metadata, default=_json_default))


def _names(names: np.ndarray | None) -> np.ndarray | None:
    """Names (N,) as UTF-8 bytes for HDF5 (None: None)."""
    if names is None:
        return None
    return np.array([n.encode("utf-8") for n in names.tolist()], dtype=bytes)


_STR = h5py.string_dtype("utf-8")


#: the largest chunk of a ground-truth field (bytes): a whole field up to it
TRUTH_CHUNK_BYTES = 1 << 22


def _one_chunk(data: np.ndarray) -> tuple[int, ...]:
    """A truth field's chunk shape: the whole field (every column), of at most
    :data:`TRUTH_CHUNK_BYTES`."""
    row = max(1, data[:1].nbytes)
    return (max(1, min(len(data), TRUTH_CHUNK_BYTES // row)), *data.shape[1:])


def _narrow(name: str, data: np.ndarray) -> np.ndarray:
    """A truth field as stored (:func:`stored_seen`): what the sensor sees in float32
    (relative 6e-8: 0.6 ns of a 10 ms delay, 60 um at 1 km), object indices int32;
    the rest as given."""
    if name == "object_index":
        return data.astype(np.int32)
    return data.astype(np.float32) if name in STORED_SEEN else data


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"metadata value of type {type(obj).__name__} is not JSON-serialisable")


def save_recording(path: str | Path, recording: Recording, **kw) -> Path:
    """Write one recording (see :func:`save_recordings`)."""
    return save_recordings(path, [recording], **kw)


# ---------------------------------------------------------------- reading


def load_recordings(
    path: str | Path, *, max_bytes: int = MAX_SAMPLE_BYTES, call: Waveform | None = None
) -> list[Recording]:
    """Read every recording of a file, validating every field (see :func:`load_recording`)."""
    path = Path(path)
    if reader := reader_of(path):
        return reader.read(path, call=call, max_bytes=max_bytes)
    return recording_schema.read_all(path, max_bytes)


def load_recording(
    path: str | Path,
    index: int = 0,
    *,
    max_bytes: int = MAX_SAMPLE_BYTES,
    call: Waveform | None = None,
) -> Recording:
    """Read recording `index` of a file (negative: from the end), and only that one.

    A file in another registered format (:mod:`processing.formats.registry`: CHIRP) is read as
    well; `call` is the emitted call
    for one that does not say it (ignored otherwise: a file of ours, and a CHIRP file
    whose transmitter signal is a sweep :func:`processing.sensor.calls.fit_sweep` fits).

    Every field is checked: samples finite and at most `max_bytes` bytes (declared
    shape times item size, checked before reading), compression filters available,
    checksums, array geometry, waveform below Nyquist, attributes, pose and ground
    truth. A problem raises :class:`RecordingFileError` naming the file and field.
    """
    path = Path(path)
    if reader := reader_of(path):
        return reader.read(path, call=call, max_bytes=max_bytes, index=index)[0]
    return recording_schema.read_index(path, index, max_bytes)


def count_recordings(path: str | Path) -> int:
    """How many recordings a file holds (without reading them)."""
    if reader := reader_of(path):
        return reader.count(path)
    return recording_schema.count(Path(path))
