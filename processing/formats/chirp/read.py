"""Reading CHIRP files into Recordings (the layout: :mod:`processing.formats.chirp.write`).

One :class:`Reader` per open file; every refusal is a
:class:`processing.formats.chirp.write.ChirpFileError` naming the file and the HDF5 field.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np

from processing.base.frames import euler_of, matrix_of_quaternion
from processing.formats.chirp import rig
from processing.formats.chirp.names import (
    ACOUSTIC,
    ODOMETRY,
    OUR_SCHEMA,
    OURS,
    TRANSMITTER,
    ChirpFileError,
    lidar_name,
    our_lidar,
)
from processing.formats.h5attrs import attribute_text
from processing.sensor.arrays import Array
from processing.sensor.calibration import on_load
from processing.sensor.calls import FIT_MIN_CORRELATION, Waveform, fit_sweep
from processing.sensor.pointcloud import PointCloud
from processing.sensor.recording import MAX_SAMPLE_BYTES, GroundTruth, Recording, with_last_points

__all__ = ["Reader", "DEFAULT_SPEED_OF_SOUND_M_S", "is_chirp", "count_chirp", "read_chirp"]

DEFAULT_SPEED_OF_SOUND_M_S = 343.0
"""Speed of sound of a CHIRP recording that does not say it (dry air at 20 °C)."""


_text = attribute_text  # the one reading of a text attribute


class Reader:
    """An open CHIRP file (a context manager)."""

    def __init__(self, path: Path, max_bytes: int = MAX_SAMPLE_BYTES) -> None:
        self.path, self.max_bytes = Path(path), max_bytes

    def fail(self, msg: str, key: str | None = None, value=...) -> ChirpFileError:
        return ChirpFileError(msg, file=self.path, key=key, value=value)

    def __enter__(self) -> Reader:
        if not self.path.is_file():
            raise self.fail("no such file")
        try:
            self.f = h5py.File(self.path, "r")
        except OSError as exc:
            raise self.fail(f"not an HDF5 file ({exc})") from None
        try:
            self._locate()
        except BaseException:
            self.f.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.f.close()

    def _locate(self) -> None:
        f = self.f
        if _text(f.attrs.get("format")) != "chirp":
            raise self.fail("not a CHIRP file", key="format", value=f.attrs.get("format"))
        name = _text(f.attrs.get("reference_sensor")) or ACOUSTIC
        self.ac = self.group(f"/sensors/{name}")
        self.signals = self.dataset(self.ac, "data/signals", 3, "f")
        self.n, self.T, self.M = self.signals.shape
        self.fs = self.number(self.ac, "sample_rate_hz")
        tx = f.get(f"/sensors/{TRANSMITTER}")
        self.tx = tx if isinstance(tx, h5py.Group) else None
        ours = f.get(OURS)
        ok = isinstance(ours, h5py.Group) and _text(ours.attrs.get("schema")) == OUR_SCHEMA
        self.ours = ours if ok else None
        #: a rig's file (ours, :mod:`.rig`): each capture's acoustic sensor and row
        self.rig = None
        if self.ours is not None and "capture_sensor" in self.ours:
            self.rig = (
                np.asarray(self.read(self.ours["capture_sensor"]), int),
                np.asarray(self.read(self.ours["capture_row"]), int),
            )

    def place(self, k: int) -> tuple[h5py.Group, int]:
        """Capture `k`'s acoustic sensor group and its row there (a rig's file: the
        sonar that fired; else the reference sensor, row k)."""
        if self.rig is None:
            return self.ac, int(k)
        n, row = int(self.rig[0][k]), int(self.rig[1][k])
        return self.group(f"/sensors/{rig.acoustic_name(n)}"), row

    # -- fields

    def group(self, key: str) -> h5py.Group:
        g = self.f.get(key)
        if not isinstance(g, h5py.Group):
            raise self.fail("missing group", key=key)
        return g

    def dataset(self, g: h5py.Group, name: str, ndim: int, kinds: str) -> h5py.Dataset:
        key = f"{g.name}/{name}"
        d = g.get(name)
        if not isinstance(d, h5py.Dataset):
            raise self.fail("missing", key=key)
        if d.ndim != ndim or d.dtype.kind not in kinds:
            raise self.fail(
                f"expected {ndim} dimensions of kind {kinds!r}",
                key=key,
                value=f"{d.shape} {d.dtype}",
            )
        return d

    def read(self, d: h5py.Dataset, sel=()):
        try:
            return d[sel]
        except OSError as exc:
            raise self.fail(f"cannot be read: corrupted ({exc})", key=d.name) from None

    def number(self, g: h5py.Group, name: str) -> float:
        v = g.attrs.get(name)
        if not (np.ndim(v) == 0 and isinstance(v, int | float | np.number) and np.isfinite(v)):
            raise self.fail("missing or not a finite number", key=f"{g.name}.{name}", value=v)
        if not v > 0:
            raise self.fail("must be positive", key=f"{g.name}.{name}", value=float(v))
        return float(v)

    def matrix(self, g: h5py.Group | None, name: str) -> np.ndarray:
        """A 4x4 rigid transform (identity when absent)."""
        if g is None or name not in g:
            return np.eye(4)
        T = np.asarray(self.read(self.dataset(g, name, 2, "f")), float)
        R = T[:3, :3] if T.shape in ((4, 4), (3, 4)) else np.zeros((3, 3))
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or not np.all(np.isfinite(T)):
            raise self.fail("must be a finite rigid 4x4 transform", key=f"{g.name}/{name}")
        out = np.eye(4)
        out[:3] = T[:3]
        return out

    def timestamps(self, g: h5py.Group) -> np.ndarray | None:
        if "data/timestamps" not in g:
            return None
        return np.asarray(self.read(self.dataset(g, "data/timestamps", 1, "fiu")), float)

    # -- the file's recordings

    def count(self) -> int:
        if self.ours is not None:
            return int(np.max(self.read(self.ours["capture_recording"]), initial=-1)) + 1
        return self.n

    def recordings(self, index, call, c) -> list[Recording]:
        n = self.count()
        if index is not None and not -n <= index < n:
            raise self.fail(f"index out of range ({n} recordings)", key="index", value=index)
        wanted = range(n) if index is None else [index % n]
        if self.ours is not None:
            owner = np.asarray(self.read(self.ours["capture_recording"]), int)
            groups = [np.flatnonzero(owner == i) for i in wanted]
        else:
            groups = [np.array([i]) for i in wanted]
        need = sum(self.capture_bytes(k) for g in groups for k in g)
        if need > self.max_bytes:
            raise self.fail(
                f"{need / 2**30:.3g} GiB of samples, more than the limit max_bytes = "
                f"{self.max_bytes / 2**30:.3g} GiB",
                key=self.signals.name,
                value=self.signals.shape,
            )
        array, emitter_note = self.array()
        wf = None if self.ours is not None else self.call(call)  # (call, its start)
        return [self.recording(i, g, array, wf, c, emitter_note) for i, g in zip(wanted, groups)]

    def capture_bytes(self, k: int) -> int:
        """The bytes of capture `k`'s samples."""
        if self.rig is None:
            return self.T * self.M * self.signals.dtype.itemsize
        ac, _ = self.place(k)
        d = self.dataset(ac, "data/signals", 3, "f")
        return int(np.prod(d.shape[1:])) * d.dtype.itemsize

    def samples(self, captures: np.ndarray) -> np.ndarray:
        rows = []
        for k in captures:
            ac, row = self.place(int(k))
            d = self.signals if ac == self.ac else self.dataset(ac, "data/signals", 3, "f")
            rows.append(np.asarray(self.read(d, row), np.float32).T)
        x = np.stack(rows)
        if not np.all(np.isfinite(x)):
            raise self.fail("samples are NaN or infinite", key=d.name)
        if self.ours is not None and "capture_sha256" in self.ours:
            sums = self.read(self.ours["capture_sha256"])
            for k, block in zip(captures, x):
                data = np.ascontiguousarray(block.T, "<f4").data
                if hashlib.sha256(data).hexdigest() != _text(sums[k]):
                    raise self.fail(
                        f"capture {k} differs from the checksum written with it (corrupted)",
                        key=self.place(int(k))[0].name + "/data/signals",
                    )
        return x

    def array(self, n: int = 0) -> tuple[Array, bool]:
        """The receiver array in the acoustic sensor's frame, the emitter from the
        transmitter's to_origin (and whether that was missing: emitter at 0); `n`: a
        rig's sonar (its acoustic sensor and transmitter NN)."""
        ac, tx_group, extras = self.ac, self.tx, "array"
        if n:
            ac = self.group(f"/sensors/{rig.acoustic_name(n)}")
            tx_group = self.group(f"/sensors/{rig.transmitter_name(n)}")
            extras = f"array_{n:02d}"
        key = f"{ac.name}/calibration/receiver_relative_translations"
        cal = ac.get("calibration")
        if not isinstance(cal, h5py.Group):
            raise self.fail("missing: the microphone positions", key=key)
        pos = np.asarray(self.read(self.dataset(cal, "receiver_relative_translations", 2, "f")))
        M = self.dataset(ac, "data/signals", 3, "f").shape[2]
        if pos.shape != (M, 3) or not np.all(np.isfinite(pos)):
            raise self.fail(f"must be finite ({M}, 3) metres", key=key, value=pos.shape)
        if len(np.unique(pos, axis=0)) < len(pos):
            raise self.fail("two microphones at the same position", key=key)
        to_origin = self.matrix(cal, "to_origin")
        tx_cal = tx_group.get("calibration") if tx_group is not None else None
        missing = tx_cal is None or "to_origin" not in tx_cal
        tx = np.linalg.inv(to_origin) @ self.matrix(tx_cal, "to_origin")
        name = _text(ac.attrs.get("name")) or f"chirp {ac.name.rsplit('/', 1)[-1]}"
        channels = grid = pitch = None
        if self.ours is not None and extras in self.ours:
            a = self.ours[extras]
            name = _text(a.attrs.get("name")) or name
            channels = self.read(a["channels"]) if "channels" in a else None
            if "grid_index" in a:
                grid = self.read(a["grid_index"])
                pitch = self.pitch(a["grid_index"])
        try:
            return Array(name, pos, tx[:3, 3], grid, pitch, channels), missing
        except ValueError as exc:
            raise self.fail(str(exc), key=key) from None

    def pitch(self, grid_index: h5py.Dataset) -> tuple[float, ...]:
        """A URA's pitch (dz, dy), m, from our `grid_index`'s attribute; whatever a
        hand-edited file holds there (absent, text, an array of strings) is the
        one-line error naming it."""
        raw = grid_index.attrs.get("pitch_m")
        try:
            return tuple(float(v) for v in np.ravel(np.asarray(raw)))
        except (TypeError, ValueError):
            key = f"{grid_index.name}.pitch_m"
            shown = raw.tolist() if isinstance(raw, np.ndarray) else raw  # one line
            raise self.fail("must be the pitch (dz, dy) in metres", key=key, value=shown) from None

    def call(self, given: Waveform | None) -> tuple[Waveform, int]:
        """The sweep fitted to the transmitter's signal when it fits, else `given`; and
        the sample of the transmitter's signal at which the call starts."""
        key = f"/sensors/{TRANSMITTER}/data/signals"
        if self.tx is None or "data/signals" not in self.tx:
            if given is not None:
                return self.below_nyquist(given, "call"), 0
            raise self.fail(
                "the file has no transmitter signal, so the call is unknown: give the call "
                "(--call, or call= in Python)",
                key=key,
            )
        d = self.dataset(self.tx, "data/signals", 1, "f")
        fs = float(self.tx.attrs.get("sample_rate_hz", self.fs))
        try:
            wf, corr, start = fit_sweep(self.read(d), fs)
        except ValueError as exc:
            wf, corr = None, f"no fit: {exc}"
        if wf is not None and corr >= FIT_MIN_CORRELATION:
            return self.below_nyquist(wf, key), int(round(start * self.fs / fs))
        if given is not None:
            return self.below_nyquist(given, "call"), 0
        raise self.fail(
            f"the transmitter's signal is not a linear or hyperbolic sweep we can describe "
            f"(best fit correlates {corr if wf is None else f'{corr:.3f}'}, below "
            f"{FIT_MIN_CORRELATION}): give the call (--call, or call= in Python)",
            key=key,
        )

    def below_nyquist(self, wf: Waveform, key: str) -> Waveform:
        if max(wf.band_hz) > self.fs / 2:
            raise self.fail(
                f"the call reaches {max(wf.band_hz):g} Hz, above the Nyquist frequency "
                f"{self.fs / 2:g} Hz",
                key=key,
            )
        return wf

    def recording(self, i, captures, array, wf, c, emitter_note) -> Recording:
        x = self.samples(captures)
        if self.ours is not None:
            return self._ours(i, captures, x, array)
        k = int(captures[0])
        t_ac = self.timestamps(self.ac)
        t_tx = self.timestamps(self.tx) if self.tx is not None else None
        wf, e = wf  # the call starts `e` samples into the transmitter's signal
        if t_ac is not None and t_tx is not None and len(t_tx) == self.n:
            e += int(round((t_tx[k] - t_ac[k]) * self.fs))
        e = e if 0 <= e < self.T else 0
        meta = {"simulated": False, "source": "chirp", "chirp_file": str(self.path), "capture": k}
        if emitter_note:
            meta["emitter_assumed_at_origin"] = True
        stamp = t_tx if t_tx is not None and len(t_tx) == self.n else t_ac
        if stamp is not None:
            meta["timestamp"] = float(stamp[k])
        pose = self.pose(k, meta.get("timestamp"))
        if pose is not None:
            meta["pose"] = pose
        scans = self.scans(k)
        return Recording(
            samples=x[0],
            sample_rate_hz=self.fs,
            array=array,
            waveform=wf,
            speed_of_sound_m_s=DEFAULT_SPEED_OF_SOUND_M_S if c is None else c,
            emission_index=e,
            metadata=meta,
            lidar=scans[0] if scans else None,
            other_lidars=scans[1:],
        )

    def _ours(self, i: int, captures: np.ndarray, x: np.ndarray, array: Array) -> Recording:

        g = self.group(f"{self.ours.name}/recordings/{i:06d}")
        order = np.argsort(self.read(self.ours["capture_measurement"])[captures])
        x = x[order]
        fs, first = self.fs, int(captures[order[0]])
        if self.rig is not None:  # the sonar that fired: its array, rate, LiDAR mounting
            ac, _ = self.place(first)
            array, _ = self.array(int(self.rig[0][first]))
            fs = self.number(ac, "sample_rate_hz")
        try:
            wf = Waveform.from_dict(json.loads(_text(g.attrs["waveform"])))
            meta = json.loads(_text(self.read(g["metadata"])) or "{}")
            scans = self.scans(first)
            rec = Recording(
                samples=x[0] if len(x) == 1 else x,
                sample_rate_hz=fs,
                array=array,
                waveform=wf,
                speed_of_sound_m_s=float(g.attrs["speed_of_sound_m_s"]),
                emission_index=int(g.attrs["emission_index"]),
                metadata=meta,
                truth=self.truth(g),
                lidar=scans[0] if scans else None,
                other_lidars=scans[1:],
            )
        except (KeyError, ValueError, TypeError) as exc:
            if isinstance(exc, ChirpFileError):
                raise
            raise self.fail(f"malformed ({exc})", key=g.name) from None
        return on_load(rec, self.path)

    def truth(self, g: h5py.Group) -> GroundTruth | None:
        if "truth" not in g:
            return None
        t = g["truth"]
        fields = {n: self.read(t[n]) for n in t if isinstance(t[n], h5py.Dataset)}
        if "kind" in fields:
            fields["kind"] = np.char.decode(fields["kind"], "ascii", errors="replace")
        if "emitter" in fields:  # a rig's recording
            fields["emitter"] = np.char.decode(fields["emitter"], "utf-8")
        if "object_names" in fields:
            fields["object_names"] = tuple(
                x.decode(errors="replace") if isinstance(x, bytes) else str(x)
                for x in np.asarray(fields["object_names"]).reshape(-1)
            )
        try:
            return GroundTruth(**with_last_points(fields))
        except (TypeError, ValueError, KeyError) as exc:
            raise self.fail(f"not a ground truth ({exc})", key=t.name) from None

    # -- the other sensors, at capture k

    def _row(self, g: h5py.Group, k: int, t: float | None) -> int:
        """The row of sensor `g` for reference capture k: k itself (reference_capture),
        sync_to_reference_index[k], or the nearest timestamp."""
        if _text(g.attrs.get("sync_mode")) == "reference_capture":
            return k
        if "data/sync_to_reference_index" in g:
            return int(self.read(g["data/sync_to_reference_index"], k))
        ts = self.timestamps(g)
        if ts is None or t is None or not len(ts):
            raise self.fail("cannot be aligned to the acoustic captures", key=g.name)
        return int(np.argmin(np.abs(ts - t)))

    def pose(self, k: int, t: float | None) -> dict | None:
        """The acoustic sensor's pose in the odometry's frame at capture k (as in
        our metadata), or None without odometry."""
        odo = self.f.get(f"/sensors/{ODOMETRY}")
        if not isinstance(odo, h5py.Group):
            return None
        r = self._row(odo, k, t)
        base = np.eye(4)
        base[:3, :3] = matrix_of_quaternion(self.read(odo["data/orientation"], r))
        base[:3, 3] = self.read(odo["data/position"], r)
        link = self.matrix(self.f.get("transforms"), "base_link_to_origin")
        sensor = base @ np.linalg.inv(link) @ self.matrix(self.ac.get("calibration"), "to_origin")
        yaw, pitch, roll = np.rad2deg(euler_of(sensor[:3, :3]))
        return {
            "position_m": sensor[:3, 3].tolist(),
            "yaw_deg": float(yaw),
            "pitch_deg": float(pitch) + 0.0,  # not -0.0
            "roll_deg": float(roll),
            "time_s": float(t) if t is not None else 0.0,
        }

    def scans(self, k: int) -> tuple[PointCloud, ...]:
        """The LiDARs' scans at capture k: ``lidar_00``, ``lidar_01``, ... (a rig's)."""
        out: list[PointCloud] = []
        while isinstance(g := self.f.get(f"/sensors/{lidar_name(len(out))}"), h5py.Group):
            out.append(self.scan(k, g, our_lidar(len(out))))
        return tuple(out)

    def scan(self, k: int, g: h5py.Group, ours: str) -> PointCloud:
        """The scan of LiDAR group `g` at capture k (`ours`: our group beside it)."""
        ac, _ = self.place(k)
        if self.rig is not None:  # a rig's file: one scan per capture, beside its sonar
            r = k
        else:
            ts = self.timestamps(self.ac)
            r = self._row(g, k, None if ts is None else float(ts[k]))
        pts = np.asarray(self.read(self.dataset(g, "data/points", 3, "f"), r), float)
        n = int(self.read(g["data/point_counts"], r)) if "data/point_counts" in g else len(pts)
        keep = np.arange(len(pts)) < n
        keep &= np.all(np.isfinite(pts[:, :3]), axis=1)
        ring = when = None
        if self.ours is not None and ours in self.f:
            ring = np.asarray(self.read(self.f[f"{ours}/ring"], r))[keep]
            when = np.asarray(self.read(self.f[f"{ours}/time_s"], r))[keep]
        intensity = pts[keep, 3] if pts.shape[1] > 3 else np.zeros(int(keep.sum()))
        acoustic = self.matrix(ac.get("calibration"), "to_origin")
        to_sensor = np.linalg.inv(acoustic) @ self.matrix(g.get("calibration"), "to_origin")
        return PointCloud(
            pts[keep, :3],
            np.nan_to_num(intensity),
            to_sensor,
            ring,
            when,
            name=_text(g.attrs.get("name")) or "lidar",
            rate_hz=float(g.attrs.get("rate_hz", np.nan)),
        )


# ---------------------------------------------------------------- the entry points


def is_chirp(path: str | Path) -> bool:
    """Whether `path` is an HDF5 file whose root says ``format = "chirp"``."""
    try:
        with h5py.File(path, "r") as f:
            v = f.attrs.get("format")
    except (OSError, ValueError):
        return False
    return attribute_text(v) == "chirp"


def count_chirp(path: str | Path) -> int:
    """How many recordings :func:`read_chirp` returns (ours: as written; else one
    per capture)."""
    with Reader(Path(path)) as r:
        return r.count()


def read_chirp(
    path: str | Path,
    *,
    call: Waveform | None = None,
    index: int | None = None,
    max_bytes: int = MAX_SAMPLE_BYTES,
    speed_of_sound_m_s: float | None = None,
) -> list[Recording]:
    """The recordings of a CHIRP file (all, or only recording `index`).

    A file we wrote gives back what was written (samples as float32). Any other:
    one (M, T) recording per capture, array from ``receiver_relative_translations``,
    emitter from the transmitter's ``to_origin``, call fitted to its ``signals``
    (when that fails or there is no transmitter signal: `call`, else an error), speed of
    sound `speed_of_sound_m_s` (default 343 m/s), pose from ``odometry_00``, scans
    from ``lidar_00`` (and ``lidar_01``, ...: ``Recording.other_lidars``).
    """
    with Reader(Path(path), max_bytes) as r:
        return r.recordings(index, call, speed_of_sound_m_s)
