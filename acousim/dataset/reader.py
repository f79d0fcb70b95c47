"""Reading a generated dataset: samples as numpy arrays with their labels."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np

from .generation import MANIFEST

__all__ = ["DatasetReader", "TorchAdapter"]


class DatasetReader:
    """Random access and iteration over a dataset folder.

    ``reader[i]`` is a dict: every stored array (``snapshot``, ``range_m``,
    ``image/<method>`` in dB, ``labels/...``, ``raw``) plus ``params`` (the sample's
    scene, pose, conditions and seed).
    """

    def __init__(self, folder: str | Path, verify: bool = False) -> None:
        self.folder = Path(folder)
        path = self.folder / MANIFEST
        if not path.is_file():
            raise FileNotFoundError(f"{self.folder}: no {MANIFEST} (generation unfinished?)")
        self.manifest = json.loads(path.read_text())
        self._table = sorted(self.manifest["sample_table"], key=lambda s: s["index"])
        self._files: dict[str, h5py.File] = {}
        if verify:
            self.verify()

    def verify(self) -> None:
        """Check every shard's sha256 against the manifest."""
        import hashlib

        for sh in self.manifest["shards"]:
            digest = hashlib.sha256((self.folder / sh["file"]).read_bytes()).hexdigest()
            if digest != sh["sha256"]:
                raise ValueError(
                    f"{self.folder / sh['file']}: sha256 {digest} does not match "
                    f"the manifest's {sh['sha256']}"
                )

    def __len__(self) -> int:
        return len(self._table)

    def _file(self, name: str) -> h5py.File:
        if name not in self._files:
            self._files[name] = h5py.File(self.folder / name, "r")
        return self._files[name]

    def __getitem__(self, i: int) -> dict:
        if not -len(self) <= i < len(self):
            raise IndexError(f"sample {i} out of range ({len(self)} samples)")
        rec = self._table[i]
        g = self._file(f"shard_{rec['shard']:05d}.h5")[f"{rec['offset']:05d}"]
        raw = g.attrs["params"]
        out: dict = {"params": json.loads(raw.decode() if isinstance(raw, bytes) else raw)}

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]

        g.visititems(visit)
        return out

    def __iter__(self) -> Iterator[dict]:
        for i in range(len(self)):
            yield self[i]

    def close(self) -> None:
        for f in self._files.values():
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
