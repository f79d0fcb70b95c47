"""The recording container: :class:`Recording` (samples, array, call, time origin) and
:class:`GroundTruth` (the simulated paths), with the file format's constants. The
HDF5 file itself is read in :mod:`processing.formats.native_schema` and written in
:mod:`processing.formats.native`.

Time origin (the one convention of the whole package): sample ``n`` of a recording
is at time ``(n - emission_index) / sample_rate_hz`` after the start of the
emission.  A reflector at range r therefore peaks at ``emission_index + 2 r / c *
fs`` after the matched filter.  Nothing in :mod:`processing` adds any other delay.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from processing.base.errors import InputError, refuse_non_finite
from processing.sensor.arrays import Array
from processing.sensor.calls import Waveform
from processing.sensor.pointcloud import PointCloud
from processing.sensor.provenance import Provenance

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
        The emitted call: at least one sample long and at or below the Nyquist
        frequency (:func:`check_waveform`, the file's check too).
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
    other_lidars : tuple of PointCloud
        The scans of a rig's other LiDARs (its second, third, ...) started at the
        recording, in the rig's order (empty: one LiDAR or none); :attr:`lidars`
        gives them all.
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
    other_lidars: tuple[PointCloud, ...] = ()

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
        refuse_non_finite(x, "samples")
        if not (np.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise InputError(f"sample_rate_hz must be positive, got {self.sample_rate_hz}")
        if not (np.isfinite(self.speed_of_sound_m_s) and 200 < self.speed_of_sound_m_s < 500):
            raise InputError(
                f"speed_of_sound_m_s must be in (200, 500) m/s, got {self.speed_of_sound_m_s}"
            )
        check_waveform(self.waveform, float(self.sample_rate_hz))
        if not 0 <= int(self.emission_index) < x.shape[-1]:
            raise InputError(f"emission_index {self.emission_index} outside [0, {x.shape[-1]})")
        self._check_lidars()
        object.__setattr__(self, "samples", x)
        object.__setattr__(self, "emission_index", int(self.emission_index))
        object.__setattr__(self, "sample_rate_hz", float(self.sample_rate_hz))
        object.__setattr__(self, "speed_of_sound_m_s", float(self.speed_of_sound_m_s))

    def _check_lidars(self) -> None:
        """`lidar` None or a PointCloud; `other_lidars` PointClouds, only beside it."""
        others = tuple(self.other_lidars)
        scans = [("lidar", self.lidar)] if self.lidar is not None else []
        scans += [(f"other_lidars[{n}]", scan) for n, scan in enumerate(others)]
        for key, scan in scans:
            if not isinstance(scan, PointCloud):
                raise InputError(
                    "must be a processing.PointCloud", key=key, value=type(scan).__name__
                )
        if others and self.lidar is None:
            raise InputError("needs the first LiDAR's scan (lidar)", key="other_lidars")
        object.__setattr__(self, "other_lidars", others)

    @property
    def lidars(self) -> tuple[PointCloud, ...]:
        """Every LiDAR scan of the recording: :attr:`lidar` and :attr:`other_lidars`
        (empty: none)."""
        return () if self.lidar is None else (self.lidar, *self.other_lidars)

    @cached_property
    def provenance(self) -> Provenance:
        """Where the recording came from: simulated, real or emulated, its scene, pose
        and motion (:mod:`processing.sensor.provenance`), read from the metadata."""
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

    def with_truth(self, truth: GroundTruth | None, lidar: PointCloud | None = None) -> Recording:
        """This recording with the ground truth `truth` and the LiDAR scan `lidar`
        (None: none), its samples as they are (checked when it was made: a
        ``dataclasses.replace`` would read every sample again)."""
        out = copy.copy(self)
        object.__setattr__(out, "truth", truth)
        object.__setattr__(out, "lidar", lidar)
        out._check_lidars()
        return out


def check_waveform(
    waveform: Waveform,
    sample_rate_hz: float,
    *,
    file: str | Path | None = None,
    key: str = "waveform",
    error: type[InputError] = InputError,
) -> None:
    """The call sampled at `sample_rate_hz` (Hz) lasts at least one sample and stays
    at or below the Nyquist frequency, else `error` naming `file` and `key`: the one
    check of a :class:`Recording` (its constructor) and of its file (reader and
    writer, :mod:`processing.formats.native_schema`)."""
    if waveform.duration_s * sample_rate_hz < 1:
        raise error(
            f"lasts {waveform.duration_s:g} s, less than one sample at {sample_rate_hz:g} Hz",
            file=file,
            key=key,
        )
    top = max(waveform.f_start_hz, waveform.f_end_hz)
    if top > sample_rate_hz / 2:
        raise error(
            f"reaches {top:g} Hz, above the Nyquist frequency {sample_rate_hz / 2:g} Hz",
            file=file,
            key=key,
        )


_KINDS = ("direct", "specular", "scatter", "point", "diffraction")


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """The simulated paths of one recording (N paths), in SI units: where the sound
    went (the last reflection, the chain's first and last points, the object touched)
    and what the sensor sees of it (delay and arrival direction at the array centre,
    the apparent position: docs/recording-format.md, "Ground truth").  The fields
    after `velocity_world_m_s` are None in a file written before they existed."""

    position_world_m: np.ndarray
    """(N, 3) where each path's last reflection is, world frame, m."""
    position_sensor_m: np.ndarray
    """(N, 3) the same in the sensor frame, m."""
    amplitude: np.ndarray
    """(N,) path strength at the array centre (relative pressure, 1 = the emitter at
    1 m), a magnitude (edge-diffraction paths are signed in the tracer)."""
    order: np.ndarray
    """(N,) int, number of reflections (0: the direct path from the emitter; an edge
    counts as one)."""
    kind: np.ndarray
    """(N,) str, ``"direct"``, ``"specular"``, ``"scatter"``, ``"point"`` or
    ``"diffraction"``."""
    velocity_world_m_s: np.ndarray | None = None
    """(N, 3) velocity of each path's last reflection at the start of the emission,
    world frame, m/s; None for a scene without motion."""
    emitter: np.ndarray | None = None
    """(N,) str, the name of the sonar whose call each path carries (a rig's
    recording: its own and, crosstalk, the others'); None: the recording's own."""
    # what the sensor sees of each path (None: a file written before they existed)
    delay_s: np.ndarray | None = None
    """(N,) two-way delay at the array centre, s: from the start of the emission to
    the arrival of the call's start there, motion included (the delay the renderer
    used)."""
    arrival_sensor: np.ndarray | None = None
    """(N, 3) unit direction the path arrives from at the array centre, sensor frame
    (x: the array's axis), dimensionless."""
    apparent_position_sensor_m: np.ndarray | None = None
    """(N, 3) where an imaging sonar puts the echo: the array centre plus
    `arrival_sensor` times ``speed_of_sound * delay_s / 2``, sensor frame, m.  The
    reflection point for a first-order echo; for every other path where the image
    shows it (a two-bounce echo beyond its last reflection)."""
    apparent_position_world_m: np.ndarray | None = None
    """(N, 3) the same in the world frame (through the pose at the start of the
    emission), m."""
    first_point_m: np.ndarray | None = None
    """(N, 3) the path's first interaction (reflection, scatter, edge or point),
    world frame, m; NaN for the direct path."""
    last_point_m: np.ndarray | None = None
    """(N, 3) the path's last interaction, world frame, m (equal to
    `position_world_m`); NaN for the direct path."""
    object_index: np.ndarray | None = None
    """(N,) int, index into `object_names` of what the path's last interaction
    touched (-1: nothing, the direct path, or not known)."""
    object_names: tuple[str, ...] = ()
    """The objects of the scene, ``"<mesh>/<material>"`` for a mesh's faces of one
    material, the point reflector's name for a point (``"point 0"``, ...)."""

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
        known = np.zeros(kind.shape, bool)  # (half the time of a set of the names)
        for name in _KINDS:
            known |= kind == name
        bad = sorted(set(kind[~known].tolist()))
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
        if self.emitter is not None:
            names = np.asarray(self.emitter).astype(str).reshape(-1)
            if len(names) != n:
                raise InputError(f"truth emitter has {len(names)} entries, positions {n}")
            object.__setattr__(self, "emitter", names)
        self._check_seen(n)

    def _check_seen(self, n: int) -> None:
        """The fields of what the sensor sees: each absent or one row per path."""
        for name, width, finite in _SEEN:
            value = getattr(self, name)
            if value is None:
                continue
            a = np.asarray(value, np.int64 if name == "object_index" else float)
            a = a.reshape(-1, width) if width else a.reshape(-1)
            if len(a) != n:
                raise InputError(f"truth {name} has {len(a)} entries, position_world_m {n}")
            if finite and not np.all(np.isfinite(a)):
                raise InputError(f"truth {name} must be finite")
            object.__setattr__(self, name, a)
        names = tuple(str(x) for x in np.asarray(self.object_names, dtype=object).reshape(-1))
        object.__setattr__(self, "object_names", names)
        if self.object_index is not None and self.object_index.size:
            bad = (self.object_index < -1) | (self.object_index >= len(names))
            if bad.any():
                raise InputError(
                    f"truth object_index {int(self.object_index[bad][0])} is not -1 or an "
                    f"index into its {len(names)} object_names"
                )

    @property
    def has_apparent(self) -> bool:
        """Whether the paths carry what the sensor sees (delay, arrival direction,
        apparent position): False for a file written before they existed."""
        return self.apparent_position_sensor_m is not None

    def object_name(self) -> np.ndarray:
        """(N,) str, the name of each path's object ("" where none or unknown)."""
        if self.object_index is None:
            return np.full(len(self), "", dtype=object)
        names = np.array([*self.object_names, ""], dtype=object)
        return names[self.object_index]

    def select(self, keep) -> GroundTruth:
        """The paths where `keep` (a mask or indices, N) selects."""
        per_path = {
            f.name: None if getattr(self, f.name) is None else getattr(self, f.name)[keep]
            for f in fields(self)
            if f.name != "object_names"
        }
        return GroundTruth(**per_path, object_names=self.object_names)

    def __len__(self) -> int:
        return len(self.amplitude)

    def __repr__(self) -> str:
        return f"GroundTruth({len(self)} paths)"

    def echoes(self) -> GroundTruth:
        """The paths that are not the direct emitter-to-array path."""
        return self.select(self.kind != "direct")


#: the per-path fields of what the sensor sees, as files store them: (name, units)
SEEN_UNITS = (
    ("delay_s", "s"),
    ("arrival_sensor", "1"),
    ("apparent_position_sensor_m", "m"),
    ("apparent_position_world_m", "m"),
    ("first_point_m", "m"),
    ("last_point_m", "m"),
    ("object_index", "1"),
)
#: what files store of them: the last point is the last reflection
#: (``position_world_m``; NaN for the direct path), rebuilt on reading
STORED_SEEN = {k: u for k, u in SEEN_UNITS if k != "last_point_m"}


def with_last_points(fields: dict) -> dict:
    """Truth fields read from a file with ``last_point_m`` rebuilt (when the file has
    the first points): ``position_world_m``, NaN for the direct path."""
    if "first_point_m" not in fields or "last_point_m" in fields:
        return fields
    last = np.array(fields["position_world_m"], float).reshape(-1, 3)
    last[np.asarray(fields["kind"]).astype(str).reshape(-1) == "direct"] = np.nan
    return {**fields, "last_point_m": last}


#: the same: (name, columns (0: a vector), finite)
_SEEN = (
    ("delay_s", 0, True),
    ("arrival_sensor", 3, True),
    ("apparent_position_sensor_m", 3, True),
    ("apparent_position_world_m", 3, True),
    ("first_point_m", 3, False),
    ("last_point_m", 3, False),
    ("object_index", 0, True),
)
