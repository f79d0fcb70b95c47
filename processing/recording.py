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
                           motion only)
        metadata           scalar string: JSON object (pose, scene, seed, ...)
        attrs: sample_rate_hz, speed_of_sound_m_s, emission_index, array_name,
               waveform (JSON)
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import h5py
import numpy as np
from numpy.typing import DTypeLike

from .arrays import Array
from .atomic import atomic_path
from .errors import InputError
from .metadata import metadata_problem
from .pointcloud import PointCloud, read_point_cloud, write_point_cloud
from .provenance import Provenance
from .waveforms import Waveform

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

SCHEMA = "acousim.recordings"
SCHEMA_VERSION = 2
SUPPORTED_VERSIONS = (1, 2)

MAX_SAMPLE_BYTES = 4 * 2**30
"""Largest samples dataset (declared shape x item size) the loader reads: 4 GiB
(an eRTIS recording of 32 mics x 163,840 samples x float32 is 21 MB); pass
``max_bytes`` to raise it."""


class RecordingFileError(InputError):
    """A recording file that cannot be read; the message names the file and the field."""


@dataclass(frozen=True, eq=False)
class Recording:
    """One measurement (or K measurements of a static scene) of a microphone array.

    Attributes
    ----------
    samples : ndarray, shape (M, T) or (K, M, T)
        Microphone signals, M microphones in the order of `array`, T samples.
    sample_rate_hz : float
    array : Array
    waveform : Waveform
        The emitted call.
    speed_of_sound_m_s : float
    emission_index : int
        Sample index at which the emission starts (see the module docstring).
    metadata : dict
        JSON-serialisable: provenance, pose, scene, seed, device settings...; read
        where it came from through :attr:`provenance` (typed), not by key.
    truth : GroundTruth, optional
        The simulated paths (None for a real recording).
    lidar : PointCloud, optional
        A LiDAR scan taken at the recording's pose (None: none).
    """

    samples: np.ndarray
    sample_rate_hz: float
    array: Array
    waveform: Waveform
    speed_of_sound_m_s: float = 343.0
    emission_index: int = 0
    metadata: dict = field(default_factory=dict)
    truth: GroundTruth | None = None
    lidar: PointCloud | None = None

    def __repr__(self) -> str:
        shape = "x".join(str(n) for n in np.shape(self.samples))
        kind = self.provenance.kind
        return (
            f"Recording({kind}, {self.array.name!r}, samples {shape} at "
            f"{self.sample_rate_hz / 1e3:g} kHz, call {self.waveform.kind} "
            f"{self.waveform.f_start_hz / 1e3:g}->{self.waveform.f_end_hz / 1e3:g} kHz)"
        )

    def __post_init__(self) -> None:
        x = np.asarray(self.samples)
        if x.ndim not in (2, 3):
            raise InputError(f"samples must have shape (M, T) or (K, M, T), got {x.shape}")
        if not np.issubdtype(x.dtype, np.floating):
            x = x.astype(np.float64)
        if x.shape[-2] != self.array.n_mics:
            raise InputError(
                f"samples have {x.shape[-2]} channels but array {self.array.name!r} "
                f"has {self.array.n_mics} microphones"
            )
        bad = ~np.isfinite(x)
        if bad.any():
            where = np.argwhere(bad)[0]
            raise InputError(
                f"{int(bad.sum())} non-finite sample(s); first at channel {int(where[-2])}, "
                f"sample {int(where[-1])}"
                + (f", measurement {int(where[0])}" if x.ndim == 3 else ""),
                key="samples",
                value=float(x[tuple(where)]),
            )
        if not (np.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise InputError(f"sample_rate_hz must be positive, got {self.sample_rate_hz}")
        if not (np.isfinite(self.speed_of_sound_m_s) and 200 < self.speed_of_sound_m_s < 500):
            raise InputError(
                f"speed_of_sound_m_s must be in (200, 500) m/s, got {self.speed_of_sound_m_s}"
            )
        if not 0 <= int(self.emission_index) < x.shape[-1]:
            raise InputError(f"emission_index {self.emission_index} outside [0, {x.shape[-1]})")
        object.__setattr__(self, "samples", x)
        object.__setattr__(self, "emission_index", int(self.emission_index))
        object.__setattr__(self, "sample_rate_hz", float(self.sample_rate_hz))
        object.__setattr__(self, "speed_of_sound_m_s", float(self.speed_of_sound_m_s))

    @cached_property
    def provenance(self) -> Provenance:
        """Where the recording came from: simulated, real or emulated, its scene, pose
        and motion (:mod:`processing.provenance`), read from the metadata."""
        return Provenance.from_metadata(self.metadata)

    @property
    def n_samples(self) -> int:
        return self.samples.shape[-1]

    @property
    def n_measurements(self) -> int:
        """K: 1 for an (M, T) recording."""
        return 1 if self.samples.ndim == 2 else self.samples.shape[0]

    def time_s(self) -> np.ndarray:
        """Time of each sample after the emission, shape (T,)."""
        return (np.arange(self.n_samples) - self.emission_index) / self.sample_rate_hz

    def with_samples(self, samples: np.ndarray) -> Recording:
        return replace(self, samples=samples)


_KINDS = ("direct", "specular", "scatter", "point", "diffraction")


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """The simulated paths of one recording (N paths), in SI units.

    Attributes
    ----------
    position_world_m, position_sensor_m : ndarray, shape (N, 3)
        Where each path's last reflection is, in the world and the sensor frame (m).
    amplitude : ndarray, shape (N,)
        Path strength at the array centre (relative pressure, 1 = the emitter at 1 m),
        a magnitude (edge-diffraction paths are signed in the tracer).
    order : ndarray, shape (N,), int
        Number of reflections (0: the direct path from the emitter; an edge counts as
        one).
    kind : ndarray, shape (N,), str
        ``"direct"``, ``"specular"``, ``"scatter"``, ``"point"`` or ``"diffraction"``.
    velocity_world_m_s : ndarray, shape (N, 3), optional
        Velocity of each path's last reflection (world frame, m/s) at the start of
        the emission; None for a scene without motion.
    """

    position_world_m: np.ndarray
    position_sensor_m: np.ndarray
    amplitude: np.ndarray
    order: np.ndarray
    kind: np.ndarray
    velocity_world_m_s: np.ndarray | None = None

    def __post_init__(self) -> None:
        pw = np.asarray(self.position_world_m, float).reshape(-1, 3)
        ps = np.asarray(self.position_sensor_m, float).reshape(-1, 3)
        amp = np.asarray(self.amplitude, float).reshape(-1)
        order = np.asarray(self.order).reshape(-1)
        kind = np.asarray(self.kind).astype(str).reshape(-1)
        n = len(pw)
        for name, a in (("position_sensor_m", ps), ("amplitude", amp), ("order", order)):
            if len(a) != n:
                raise InputError(f"truth {name} has {len(a)} entries, position_world_m {n}")
        if len(kind) != n:
            raise InputError(f"truth kind has {len(kind)} entries, position_world_m {n}")
        if not (np.all(np.isfinite(pw)) and np.all(np.isfinite(ps)) and np.all(np.isfinite(amp))):
            raise InputError("truth positions and amplitudes must be finite")
        if order.size and (order.dtype.kind not in "iu" or order.min() < 0):
            raise InputError(f"truth order must be non-negative integers, got {order.dtype}")
        bad = sorted(set(kind.tolist()) - set(_KINDS))
        if bad:
            raise InputError(f"truth kind {bad[0]!r} is not one of {_KINDS}")
        object.__setattr__(self, "position_world_m", pw)
        object.__setattr__(self, "position_sensor_m", ps)
        object.__setattr__(self, "amplitude", amp)
        object.__setattr__(self, "order", order.astype(np.int64))
        object.__setattr__(self, "kind", kind)
        if self.velocity_world_m_s is not None:
            vel = np.asarray(self.velocity_world_m_s, float).reshape(-1, 3)
            if len(vel) != n:
                raise InputError(f"truth velocity_world_m_s has {len(vel)} entries, positions {n}")
            if not np.all(np.isfinite(vel)):
                raise InputError("truth velocities must be finite")
            object.__setattr__(self, "velocity_world_m_s", vel)

    def __len__(self) -> int:
        return len(self.amplitude)

    def __repr__(self) -> str:
        return f"GroundTruth({len(self)} paths)"

    def echoes(self) -> GroundTruth:
        """The paths that are not the direct emitter-to-array path."""
        keep = self.kind != "direct"
        return GroundTruth(
            self.position_world_m[keep],
            self.position_sensor_m[keep],
            self.amplitude[keep],
            self.order[keep],
            self.kind[keep],
            None if self.velocity_world_m_s is None else self.velocity_world_m_s[keep],
        )


# ---------------------------------------------------------------- writing


def save_recordings(
    path: str | Path,
    recordings: Sequence[Recording],
    *,
    dtype: DTypeLike = np.float32,
    compression: str | None = None,
    checksum: bool = True,
) -> Path:
    """Write recordings to one HDF5 file, atomically (see :mod:`processing.atomic`).

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
    """The reader's checks of the fields a Recording does not check itself (the
    waveform below Nyquist, the metadata's known keys, JSON-serialisable metadata)."""
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
        ):
            if data is None:  # a scene without motion
                continue
            ds = t.create_dataset(name, data=data, **kw)
            if units:
                ds.attrs["units"] = units
    if rec.lidar is not None:
        write_point_cloud(g.create_group("lidar"), rec.lidar, opts["checksum"])
    # a dataset, not an attribute: it can exceed HDF5's 64 kB attribute limit
    g.create_dataset("metadata", data=json.dumps(rec.metadata, default=_json_default))


def _sha256(samples: np.ndarray) -> str:
    """sha256 of the samples as little-endian numbers in C order (as stored)."""
    x = np.ascontiguousarray(samples, samples.dtype.newbyteorder("<"))
    return hashlib.sha256(x.data).hexdigest()


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
    if chirp := _chirp(path):
        return chirp.read_chirp(path, call=call, max_bytes=max_bytes)
    with _open(path) as (f, version, names):
        return [_read_one(path, f["recordings"][n], version, max_bytes) for n in names]


def load_recording(
    path: str | Path,
    index: int = 0,
    *,
    max_bytes: int = MAX_SAMPLE_BYTES,
    call: Waveform | None = None,
) -> Recording:
    """Read recording `index` of a file (negative: from the end), and only that one.

    A CHIRP file (``processing.chirp``) is read as well; `call` is the emitted call
    for one that does not say it (ignored otherwise: a file of ours, and a CHIRP file
    whose transmitter signal is a sweep :func:`processing.waveforms.fit_sweep` fits).

    Every field is checked: samples finite and at most `max_bytes` bytes (declared
    shape times item size, checked before reading), compression filters available,
    checksums, array geometry, waveform below Nyquist, attributes, pose and ground
    truth. A problem raises :class:`RecordingFileError` naming the file and field.
    """
    path = Path(path)
    if chirp := _chirp(path):
        return chirp.read_chirp(path, call=call, max_bytes=max_bytes, index=index)[0]
    with _open(path) as (f, version, names):
        if not -len(names) <= index < len(names):
            raise RecordingFileError(
                f"index out of range ({len(names)} recordings)", file=path, key="index", value=index
            )
        return _read_one(path, f["recordings"][names[index]], version, max_bytes)


def count_recordings(path: str | Path) -> int:
    """How many recordings a file holds (without reading them)."""
    if chirp := _chirp(Path(path)):
        return chirp.count_chirp(path)
    with _open(Path(path)) as (_, _, names):
        return len(names)


def _chirp(path: Path):
    """The module :mod:`processing.chirp` if `path` is a CHIRP file, else None."""
    from . import chirp

    return chirp if chirp.is_chirp(path) else None


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


def _text(value) -> str | None:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    return value if isinstance(value, str) else None


def _dataset(
    path: Path, g: h5py.Group, name: str, ndim: tuple[int, ...], kind: str, units: str | None = None
) -> h5py.Dataset:
    key = f"{g.name}/{name}"
    if name not in g or not isinstance(g[name], h5py.Dataset):
        raise RecordingFileError("missing", file=path, key=key)
    d = g[name]
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
    if w.duration_s * sample_rate_hz < 1:
        raise RecordingFileError(
            f"lasts {w.duration_s:g} s, less than one sample at {sample_rate_hz:g} Hz",
            file=path,
            key=key,
        )
    top = max(w.f_start_hz, w.f_end_hz)
    if top > sample_rate_hz / 2:
        raise RecordingFileError(
            f"reaches {top:g} Hz, above the Nyquist frequency {sample_rate_hz / 2:g} Hz",
            file=path,
            key=key,
        )


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
    """The metadata keys the programs read, each checked (processing.metadata)."""
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
    fields["kind"] = np.char.decode(fields["kind"], "ascii", errors="replace")
    if "velocity_world_m_s" in t:  # scenes with motion
        name = "velocity_world_m_s"
        ds = _dataset(path, t, name, (2,), "f", "m/s")
        fields[name] = _read(path, ds, f"{key}/{name}")
    try:
        return GroundTruth(**fields)
    except ValueError as exc:
        raise RecordingFileError(str(exc), file=path, key=key) from None


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
    lidar = read_point_cloud(path, g["lidar"], RecordingFileError) if "lidar" in g else None
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
            lidar=lidar,
        )
    except (ValueError, TypeError) as exc:
        if isinstance(exc, RecordingFileError):
            raise
        raise RecordingFileError(str(exc), file=path, key=g.name) from None
    from .calibration import on_load  # a stored array calibration, applied once

    return on_load(rec, path)
