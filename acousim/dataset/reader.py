"""Reading a generated dataset: samples as numpy arrays with their labels.

Integrity: every shard is checked against the manifest's sha256 the first time it is
opened (``verify=True``, the default), and every array carries HDF5's fletcher32
checksum, so a corrupted chunk fails to read even with ``verify=False``.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np

from processing.errors import InputError

from .generation import MANIFEST
from .safety import sha256_file

__all__ = ["DatasetReader", "TorchAdapter", "DatasetError"]

_SHARD = re.compile(r"shard_\d{5}\.h5")


class DatasetError(InputError):
    """A dataset folder or shard that cannot be read: names the file and what is wrong."""


class DatasetReader:
    """Random access and iteration over a dataset folder.

    ``reader[i]`` is a dict: every stored array (``snapshot``, ``range_m``,
    ``range_index``, ``image/<method>`` in dB, ``labels/...``, ``raw``) plus ``params``
    (the sample's scene, pose, conditions, seed and steering frequency).
    ``reader.azimuth_deg`` and ``reader.elevation_deg`` are the image axes.

    Parameters
    ----------
    verify : bool
        Check each shard's sha256 against the manifest when it is first opened
        (reads each shard once more); default True.
    """

    def __init__(self, folder: str | Path, verify: bool = True) -> None:
        self.folder = Path(folder)
        path = self.folder / MANIFEST
        if not path.is_file():
            raise DatasetError(f"no {MANIFEST} (generation unfinished?)", file=self.folder)
        try:
            self.manifest = json.loads(path.read_text())
            self._table = sorted(self.manifest["sample_table"], key=lambda s: s["index"])
            self._hashes = {sh["file"]: sh["sha256"] for sh in self.manifest["shards"]}
        except (ValueError, KeyError, TypeError) as exc:
            raise DatasetError(f"malformed manifest ({exc!r})", file=path) from None
        for name in self._hashes:
            self._shard_path(name)  # confined to the folder, or an error
        self.verify_on_open = verify
        self._files: dict[str, h5py.File] = {}

    def _shard_path(self, name) -> Path:
        """A manifest's file name: only ``shard_NNNNN.h5`` inside the dataset folder."""
        if not (isinstance(name, str) and _SHARD.fullmatch(name)):
            raise DatasetError(
                "manifest names a file that is not a shard of this folder",
                file=self.folder / MANIFEST,
                key="shards.file",
                value=name,
            )
        return self.folder / name

    def verify(self) -> None:
        """Check every shard's sha256 against the manifest now."""
        for name in self._hashes:
            self._check(name)

    def _check(self, name: str) -> None:
        path = self._shard_path(name)
        if not path.is_file():
            raise DatasetError("shard missing", file=path)
        digest = sha256_file(path)
        if digest != self._hashes[name]:
            raise DatasetError(
                f"sha256 {digest} does not match the manifest's {self._hashes[name]} "
                "(corrupted: regenerate the dataset, which redoes damaged shards)",
                file=path,
            )

    def __len__(self) -> int:
        return len(self._table)

    def _file(self, name: str) -> h5py.File:
        if name not in self._files:
            if self.verify_on_open:
                self._check(name)
            self._files[name] = h5py.File(self._shard_path(name), "r")
        return self._files[name]

    def _images(self) -> None:
        if self.manifest.get("shard_format") == "chirp":
            raise DatasetError("CHIRP shards hold no images, so no image axes", file=self.folder)

    @property
    def azimuth_deg(self) -> np.ndarray:
        self._images()
        return self._file(next(iter(self._hashes)))["axes/azimuth_deg"][()]

    @property
    def elevation_deg(self) -> np.ndarray:
        self._images()
        return self._file(next(iter(self._hashes)))["axes/elevation_deg"][()]

    def __getitem__(self, i: int) -> dict:
        if not -len(self) <= i < len(self):
            raise IndexError(f"sample {i} out of range ({len(self)} samples)")
        rec = self._table[i]
        name = f"shard_{rec['shard']:05d}.h5"
        if self.manifest.get("shard_format") == "chirp":
            return self._chirp_sample(name, rec["offset"])
        g = self._file(name)[f"{rec['offset']:05d}"]
        raw = g.attrs["params"]
        out: dict = {"params": json.loads(raw.decode() if isinstance(raw, bytes) else raw)}

        def visit(key, obj):
            if isinstance(obj, h5py.Dataset):
                try:
                    out[key] = obj[()]
                except OSError as exc:
                    raise DatasetError(
                        f"cannot be read: corrupted (checksum) ({exc})",
                        file=self.folder / name,
                        key=obj.name,
                    ) from None

        g.visititems(visit)
        return out

    def _chirp_sample(self, name: str, offset: int) -> dict:
        """A sample of a CHIRP shard (``[dataset] format = "chirp"``): its parameters,
        ``raw`` (M, T), the ``labels/...`` of the ground truth and, with a LiDAR,
        ``lidar/points_m`` (P, 3, LiDAR frame) and ``lidar/intensity`` (P,)."""
        import processing as P

        if self.verify_on_open and name not in self._files:
            self._check(name)
            self._files[name] = None  # checked once; read through processing
        r = P.load_recording(self._shard_path(name), offset)
        out = {"params": r.provenance.sample or {}, "raw": r.samples}
        if r.truth is not None:
            out["labels/position_sensor_m"] = r.truth.position_sensor_m.astype(np.float32)
            out["labels/amplitude"] = r.truth.amplitude.astype(np.float32)
            out["labels/order"] = r.truth.order.astype(np.int8)
            from acousim.labels import SAMPLE_FIELDS

            for key, name, dtype, _units, _dims in SAMPLE_FIELDS:  # what the sensor sees
                if getattr(r.truth, name) is not None:
                    out[key] = getattr(r.truth, name).astype(dtype)
        if r.lidar is not None:
            out["lidar/points_m"] = r.lidar.points_m.astype(np.float32)
            out["lidar/intensity"] = r.lidar.intensity.astype(np.float32)
        return out

    def __iter__(self) -> Iterator[dict]:
        for i in range(len(self)):
            yield self[i]

    def close(self) -> None:
        for f in self._files.values():
            if f is not None:
                f.close()
        self._files.clear()

    def torch(self, keys: tuple[str, ...] = ("image/das", "labels/depth_m")) -> TorchAdapter:
        return TorchAdapter(self, keys)


class TorchAdapter:
    """Usable as a ``torch.utils.data.Dataset`` (``__len__``/``__getitem__``) without
    making torch a dependency: returns tuples of float32 numpy arrays, which torch's
    default collate turns into tensors."""

    def __init__(self, reader: DatasetReader, keys: tuple[str, ...]) -> None:
        self.reader, self.keys = reader, keys

    def __len__(self) -> int:
        return len(self.reader)

    def __getitem__(self, i: int) -> tuple[np.ndarray, ...]:
        s = self.reader[i]
        missing = [k for k in self.keys if k not in s]
        if missing:
            raise KeyError(f"sample {i} has no {missing}; stored: {sorted(s)}")
        return tuple(np.asarray(s[k], np.float32) for k in self.keys)
