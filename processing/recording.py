"""The recording container and its HDF5 file format.

Time origin (the one convention of the whole package): sample ``n`` of a recording
is at time ``(n - emission_index) / sample_rate_hz`` after the start of the
emission.  A reflector at range r therefore peaks at ``emission_index + 2 r / c *
fs`` after the matched filter.  Nothing in :mod:`processing` adds any other delay.

File layout (schema version 1)::

    /                      attrs: schema="acousim.recordings", schema_version=1
    /recordings/0000/      one group per recording, in order
        samples            (M, T) or (K, M, T) float, attrs units="1"
        array/positions    (M, 3) float, attrs units="m"
        array/emitter      (3,)   float, attrs units="m"
        array/channels     (M,)   int
        array/grid_index   (M, 2) int   (URA only; attrs pitch_m=(dz, dy))
        metadata           scalar string: JSON object (pose, scene, seed, truth, ...)
        attrs: sample_rate_hz, speed_of_sound_m_s, emission_index, array_name,
               waveform (JSON)
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import h5py
import numpy as np

from .arrays import Array
from .errors import InputError
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
]

SCHEMA = "acousim.recordings"
SCHEMA_VERSION = 1


class RecordingFileError(ValueError):
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
        JSON-serialisable: pose, scene, seed, ``simulated`` (bool), device settings...
    """

    samples: np.ndarray
    sample_rate_hz: float
    array: Array
    waveform: Waveform
    speed_of_sound_m_s: float = 343.0
    emission_index: int = 0
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        x = np.asarray(self.samples)
        if x.ndim not in (2, 3):
            raise ValueError(f"samples must have shape (M, T) or (K, M, T), got {x.shape}")
        if not np.issubdtype(x.dtype, np.floating):
            x = x.astype(np.float64)
        if x.shape[-2] != self.array.n_mics:
            raise ValueError(
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
            raise ValueError(f"sample_rate_hz must be positive, got {self.sample_rate_hz}")
        if not (np.isfinite(self.speed_of_sound_m_s) and 200 < self.speed_of_sound_m_s < 500):
            raise ValueError(
                f"speed_of_sound_m_s must be in (200, 500) m/s, got {self.speed_of_sound_m_s}"
            )
        if not 0 <= int(self.emission_index) < x.shape[-1]:
            raise ValueError(f"emission_index {self.emission_index} outside [0, {x.shape[-1]})")
        object.__setattr__(self, "samples", x)
        object.__setattr__(self, "emission_index", int(self.emission_index))
        object.__setattr__(self, "sample_rate_hz", float(self.sample_rate_hz))
        object.__setattr__(self, "speed_of_sound_m_s", float(self.speed_of_sound_m_s))

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


def _atomic_path(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.part")


def save_recordings(
    path: str | Path, recordings: Sequence[Recording], *, compression: str | None = None
) -> Path:
    """Write recordings to one HDF5 file, atomically (temporary name, then rename).

    `compression` is an h5py filter ("gzip", "lzf") for the samples; none by default:
    recorded noise does not compress (gzip saves 4 % of a noisy recording and costs
    70 times the write time), a noise-free simulation does.
    """
    path = Path(path)
    tmp = _atomic_path(path)
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["schema"] = SCHEMA
            f.attrs["schema_version"] = SCHEMA_VERSION
            group = f.create_group("recordings")
            for i, rec in enumerate(recordings):
                _write_one(group.create_group(f"{i:04d}"), rec, compression)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _write_one(g: h5py.Group, rec: Recording, compression: str | None) -> None:
    d = g.create_dataset("samples", data=rec.samples, compression=compression)
    d.attrs["units"] = "1"
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
    # a dataset, not an attribute: ground truth can exceed HDF5's 64 kB attribute limit
    g.create_dataset("metadata", data=json.dumps(rec.metadata, default=_json_default))


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"metadata value of type {type(obj).__name__} is not JSON-serialisable")


def save_recording(path: str | Path, recording: Recording, **kw) -> Path:
    """Write one recording (see :func:`save_recordings`)."""
    return save_recordings(path, [recording], **kw)


def load_recordings(path: str | Path) -> list[Recording]:
    """Read every recording of a file, validating the schema, shapes, dtypes and units."""
    path = Path(path)
    if not path.is_file():
        raise RecordingFileError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise RecordingFileError(f"{path}: not an HDF5 file ({exc})") from None
    with f:
        if f.attrs.get("schema") != SCHEMA:
            raise RecordingFileError(
                f"{path}: attribute 'schema' is {f.attrs.get('schema')!r}, expected {SCHEMA!r}"
            )
        version = int(f.attrs.get("schema_version", -1))
        if version != SCHEMA_VERSION:
            raise RecordingFileError(
                f"{path}: schema_version {version} is not supported (this is {SCHEMA_VERSION})"
            )
        if "recordings" not in f:
            raise RecordingFileError(f"{path}: missing group 'recordings'")
        return [_read_one(path, g) for _, g in sorted(f["recordings"].items())]


def load_recording(path: str | Path, index: int = 0) -> Recording:
    """Read recording `index` of a file."""
    recs = load_recordings(path)
    if not -len(recs) <= index < len(recs):
        raise RecordingFileError(f"{path}: index {index} out of range ({len(recs)} recordings)")
    return recs[index]


def _field(
    path: Path, g: h5py.Group, name: str, ndim: tuple[int, ...], kind: str, units: str | None = None
) -> np.ndarray:
    where = f"{path}: {g.name}/{name}"
    if name not in g:
        raise RecordingFileError(f"{where}: missing")
    d = g[name]
    if d.ndim not in ndim:
        raise RecordingFileError(f"{where}: expected {ndim} dimensions, got shape {d.shape}")
    if d.dtype.kind not in kind:
        raise RecordingFileError(f"{where}: dtype {d.dtype} not allowed (kinds {kind!r})")
    if units is not None and d.attrs.get("units") != units:
        raise RecordingFileError(f"{where}: units {d.attrs.get('units')!r}, expected {units!r}")
    return d[()]


def _attr(path: Path, g: h5py.Group, name: str):
    if name not in g.attrs:
        raise RecordingFileError(f"{path}: {g.name} attribute {name!r} missing")
    return g.attrs[name]


def _metadata(path: Path, g: h5py.Group) -> dict:
    if "metadata" not in g:
        raise RecordingFileError(f"{path}: {g.name}/metadata: missing")
    raw = g["metadata"][()]
    try:
        meta = json.loads(raw.decode() if isinstance(raw, bytes) else raw)
    except (ValueError, AttributeError) as exc:
        raise RecordingFileError(f"{path}: {g.name}/metadata: not JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise RecordingFileError(f"{path}: {g.name}/metadata: must be a JSON object")
    return meta


def _read_one(path: Path, g: h5py.Group) -> Recording:
    samples = _field(path, g, "samples", (2, 3), "f", "1")
    pos = _field(path, g, "array/positions", (2,), "f", "m")
    emitter = _field(path, g, "array/emitter", (1,), "f", "m")
    channels = _field(path, g, "array/channels", (1,), "iu")
    grid_index = pitch = None
    if "array/grid_index" in g:
        grid_index = _field(path, g, "array/grid_index", (2,), "iu")
        pitch = tuple(g["array/grid_index"].attrs["pitch_m"])
    try:
        array = Array(str(_attr(path, g, "array_name")), pos, emitter, grid_index, pitch, channels)
        waveform = Waveform.from_dict(json.loads(_attr(path, g, "waveform")))
        return Recording(
            samples=samples,
            sample_rate_hz=float(_attr(path, g, "sample_rate_hz")),
            array=array,
            waveform=waveform,
            speed_of_sound_m_s=float(_attr(path, g, "speed_of_sound_m_s")),
            emission_index=int(_attr(path, g, "emission_index")),
            metadata=_metadata(path, g),
        )
    except (ValueError, TypeError, KeyError) as exc:
        if isinstance(exc, RecordingFileError):
            raise
        raise RecordingFileError(f"{path}: {g.name}: {exc}") from None
