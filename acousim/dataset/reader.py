"""Reading a generated dataset: samples as numpy arrays with their labels.

Integrity: every shard is checked against the manifest's sha256 the first time it is
opened (``verify=True``, the default), and every array carries HDF5's fletcher32
checksum, so a corrupted chunk fails to read even with ``verify=False``.
"""

from __future__ import annotations

import json
import os
import re
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

import processing as P
from acousim.dataset.generation import MANIFEST
from acousim.dataset.safety import sha256_file
from acousim.dataset.torch_samples import TorchSamples
from acousim.imaging.labels import SAMPLE_FIELDS
from processing.base.errors import InputError
from processing.formats.h5attrs import attribute_text

__all__ = ["DatasetReader", "TorchAdapter", "TorchSamples", "DatasetError"]

_SHARD = re.compile(r"shard_\d{5}\.h5")

OPEN_SHARDS = 16
"""Shards a :class:`DatasetReader` keeps open at most (least recently read closed
first): a shuffled epoch over thousands of shards stays far below the usual limit of
1024 open files per process, per DataLoader worker."""


class DatasetError(InputError):
    """A dataset folder or shard that cannot be read: names the file and what is wrong."""


class DatasetReader:
    """Random access and iteration over a dataset folder.

    ``reader[i]`` is a dict: every stored array under its name in the shard
    (docs/dataset-format.md: ``range_m`` (R,) m, ``range_index`` (R_kept,),
    ``snapshot`` (M, R_kept) complex64, ``image/<method>`` (R, E, A) float16 dB with
    the floor at gated bins, ``peaks/<method>/index`` (P, 3) and ``level_db`` (P,),
    ``labels/...`` (N paths), ``labels/depth_m`` (E, A) m, ``raw`` (M, T)) plus
    ``params`` (the sample's scene, pose, conditions, seed, steering frequency and
    speed of sound). ``azimuth_deg``, ``elevation_deg`` and ``range_m`` are the image
    axes, the same for every sample; :meth:`torch` gives fixed-shape samples for
    PyTorch.

    Parameters
    ----------
    folder : str or Path
        The dataset folder (holding ``manifest.json``).
    verify : bool
        Check each shard's sha256 against the manifest when it is first opened
        (reads each shard once more); default True.
    open_shards : int
        Shards kept open at most (default :data:`OPEN_SHARDS`, 16): the least
        recently read one is closed when another is opened (each shard is verified
        once, not at every reopening).

    A reader can be handed to the worker processes of a ``torch.utils.data.DataLoader``
    (forked or spawned): a process never uses the open files of another one (a
    pickled reader carries none; a forked one drops those it inherited, unused), so
    each worker opens its own, at most `open_shards`.

    Attributes
    ----------
    folder : Path
        The dataset folder.
    manifest : dict
        ``manifest.json``: the dataset's spec, inputs and shards with their sha256
        (the samples' parameters: ``reader[i]["params"]``, and each shard's sidecar
        ``shard_NNNNN.json``; a manifest of an earlier acousim also lists them, as
        ``sample_table``).
    verify_on_open : bool
        The `verify` given.
    """

    def __init__(
        self, folder: str | Path, verify: bool = True, *, open_shards: int = OPEN_SHARDS
    ) -> None:
        if not (isinstance(open_shards, int) and open_shards >= 1):
            raise InputError("must be an integer >= 1", key="open_shards", value=open_shards)
        self.folder = Path(folder)
        path = self.folder / MANIFEST
        if not path.is_file():
            raise DatasetError(f"no {MANIFEST} (generation unfinished?)", file=self.folder)
        try:
            self.manifest = json.loads(path.read_text())
            self._hashes = {sh["file"]: sh["sha256"] for sh in self.manifest["shards"]}
            self._table = _sample_table(self.manifest)
        except (ValueError, KeyError, TypeError) as exc:
            raise DatasetError(f"malformed manifest ({exc!r})", file=path) from None
        for name in self._hashes:
            self._shard_path(name)  # confined to the folder, or an error
        self.verify_on_open = verify
        self.open_shards = open_shards
        self._files: OrderedDict[str, h5py.File] = OrderedDict()  # least recent first
        self._verified: set[str] = set()
        self._pid = os.getpid()

    def __getstate__(self) -> dict:
        """Pickled (a spawned DataLoader worker) without open files."""
        state = self.__dict__.copy()
        state["_files"] = OrderedDict()
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._pid = os.getpid()

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
        """Number of samples."""
        return len(self._table)

    def _verify_once(self, name: str) -> None:
        if self.verify_on_open and name not in self._verified:
            self._check(name)
            self._verified.add(name)

    def _file(self, name: str) -> h5py.File:
        """Shard `name`, open; the least recently read shard closed beyond
        ``open_shards``. In a forked process, the parent's files are dropped unused
        (HDF5 files must not be shared across a fork)."""
        if self._pid != os.getpid():
            self._files, self._pid = OrderedDict(), os.getpid()
        if name in self._files:
            self._files.move_to_end(name)
            return self._files[name]
        self._verify_once(name)
        while len(self._files) >= self.open_shards:
            self._files.popitem(last=False)[1].close()
        f = self._files[name] = h5py.File(self._shard_path(name), "r")
        return f

    def _images(self) -> None:
        if self.manifest.get("shard_format") == "chirp":
            raise DatasetError("CHIRP shards hold no images, so no image axes", file=self.folder)

    def _axes(self) -> h5py.Group:
        self._images()
        return self._file(next(iter(self._hashes)))["axes"]

    @property
    def azimuth_deg(self) -> np.ndarray:
        """(A,) float64, degrees: the image grid's azimuths (our shards only)."""
        return self._axes()["azimuth_deg"][()]

    @property
    def elevation_deg(self) -> np.ndarray:
        """(E,) float64, degrees: the image grid's elevations (our shards only)."""
        return self._axes()["elevation_deg"][()]

    @property
    def range_m(self) -> np.ndarray:
        """(R,) float64, m: the images' range axis, the same in every sample (schema
        3; older shards: each sample's ``range_m``)."""
        axes = self._axes()
        if "range_m" not in axes:
            raise DatasetError(
                "shards of schema < 3 have a range axis per sample", file=self.folder
            )
        return axes["range_m"][()]

    @property
    def floor_db(self) -> float:
        """The images' floor, dB relative to each image's maximum: the value of the
        range bins the gate left out and of cells below it."""
        return float(self._axes().attrs.get("floor_db", -60.0))

    @property
    def max_peaks(self) -> int:
        """Peaks stored per image at most (the spec's ``store.max_peaks``): the padded
        count of :class:`TorchSamples`' peaks."""
        return int(self._axes().attrs["max_peaks"])

    def __getitem__(self, i: int) -> dict:
        """Sample `i` (negative: from the end) as a dict (see the class docstring);
        IndexError out of range, DatasetError for a corrupted shard."""
        if not -len(self) <= i < len(self):
            raise IndexError(f"sample {i} out of range ({len(self)} samples)")
        shard, offset = self._table[i]
        name = f"shard_{shard:05d}.h5"
        if self.manifest.get("shard_format") == "chirp":
            return self._chirp_sample(name, offset)
        g = self._file(name)[f"{offset:05d}"]
        try:
            params = json.loads(attribute_text(g.attrs.get("params")) or "")
        except ValueError as exc:  # absent, an array, not JSON: a foreign or edited shard
            raise DatasetError(
                f"malformed params attribute ({exc})", file=self.folder / name, key=g.name
            ) from None
        out: dict = {"params": params}

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
        self._verify_once(name)  # read through processing, which closes the file
        r = P.load_recording(self._shard_path(name), offset)
        out = {"params": r.provenance.sample or {}, "raw": r.samples}
        if r.truth is not None:
            out["labels/position_sensor_m"] = r.truth.position_sensor_m.astype(np.float32)
            out["labels/amplitude"] = r.truth.amplitude.astype(np.float32)
            out["labels/order"] = r.truth.order.astype(np.int8)

            for key, name, dtype, _units, _dims in SAMPLE_FIELDS:  # what the sensor sees
                if getattr(r.truth, name) is not None:
                    out[key] = getattr(r.truth, name).astype(dtype)
        if r.lidar is not None:
            out["lidar/points_m"] = r.lidar.points_m.astype(np.float32)
            out["lidar/intensity"] = r.lidar.intensity.astype(np.float32)
        return out

    def __iter__(self) -> Iterator[dict]:
        """Every sample in index order."""
        for i in range(len(self)):
            yield self[i]

    def close(self) -> None:
        """Close the shards opened so far (reopened on the next read)."""
        if self._pid == os.getpid():  # a forked process leaves its parent's files alone
            for f in self._files.values():
                f.close()
        self._files.clear()

    def torch(
        self,
        keys: tuple[str, ...] | None = None,
        *,
        method: str = "das",
        mask: bool = False,
        max_paths: int = 256,
        max_points: int | None = None,
    ) -> TorchSamples | TorchAdapter:
        """This dataset as a map-style PyTorch dataset (``len`` and ``[i]``), batched
        by the stock ``torch.utils.data.DataLoader`` with its default collate; torch
        itself is not needed to make it.

        Without `keys`: a :class:`TorchSamples`, one dict of fixed-shape arrays per
        sample (the image of `method`, its peaks, pose, truth; `mask` adds the gate
        as a second image channel; `max_paths` and `max_points`: the padded counts of
        the truth paths and LiDAR points), see docs/dataset-format.md. With `keys`
        (stored array names, e.g. ``("image/das", "labels/depth_m")``): a
        :class:`TorchAdapter` of tuples of those arrays as float32, as before.
        """
        if keys is not None:
            return TorchAdapter(self, tuple(keys))
        return TorchSamples(
            self, method=method, mask=mask, max_paths=max_paths, max_points=max_points
        )


def _sample_table(manifest: dict) -> Sequence[tuple[int, int]]:
    """(shard, offset) of each sample, by index: sample i is sample i % shard_size of
    shard i // shard_size (how generation groups them), checked against the shards'
    sample counts; a manifest of an earlier acousim lists them (``sample_table``)."""
    if "sample_table" in manifest:
        rows = sorted(manifest["sample_table"], key=lambda s: s["index"])
        return [(int(s["shard"]), int(s["offset"])) for s in rows]
    n, size = int(manifest["samples"]), int(manifest["shard_size"])
    counts = [int(sh["samples"]) for sh in manifest["shards"]]
    if size < 1 or counts != [min(size, n - k * size) for k in range(-(-n // size))]:
        raise ValueError(f"shards of {counts} samples, not {n} in shards of {size}")
    return _Locations(n, size)


@dataclass(frozen=True)
class _Locations(Sequence):
    """(shard, offset) of sample i of `n` in shards of `size`, computed."""

    n: int
    size: int

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i):  # an int: negative from the end, IndexError out of range
        return divmod(range(self.n)[i], self.size)


class TorchAdapter:
    """Usable as a ``torch.utils.data.Dataset`` (``__len__``/``__getitem__``) without
    making torch a dependency: ``[i]`` is a tuple of the stored arrays named by
    `keys`, as float32 numpy arrays, which torch's default collate turns into
    tensors (batchable when each key has one shape across samples: the images, the
    depth maps; not the ragged ``labels/...`` of the paths). `reader`: the
    :class:`DatasetReader`; `keys`: the names of stored arrays."""

    def __init__(self, reader: DatasetReader, keys: tuple[str, ...]) -> None:
        self.reader, self.keys = reader, keys

    def __len__(self) -> int:
        """Number of samples."""
        return len(self.reader)

    def __getitem__(self, i: int) -> tuple[np.ndarray, ...]:
        """The arrays of sample `i` named by ``keys``, float32; KeyError if one is not
        stored."""
        s = self.reader[i]
        missing = [k for k in self.keys if k not in s]
        if missing:
            raise KeyError(f"sample {i} has no {missing}; stored: {sorted(s)}")
        return tuple(np.asarray(s[k], np.float32) for k in self.keys)
