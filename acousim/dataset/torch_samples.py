"""Dataset samples as fixed-shape arrays: what a training loop batches as it is.

:class:`TorchSamples` is a map-style PyTorch dataset (``len`` and ``[i]``) built
without importing torch: ``[i]`` is a dict of numpy arrays and numbers, every one of
the same shape in every sample of a dataset, so the stock
``torch.utils.data.DataLoader`` batches it with its default collate (which turns the
arrays into tensors with a leading batch axis B). Ragged data (peaks, paths, LiDAR
points) is padded to a fixed count and comes with that count. The fields, their
shapes, dtypes and units are in docs/dataset-format.md ("Training with PyTorch").
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from processing.base.errors import InputError


class Samples(Protocol):
    """What :class:`TorchSamples` reads: a :class:`acousim.dataset.DatasetReader`."""

    folder: Path
    manifest: dict
    range_m: np.ndarray
    elevation_deg: np.ndarray
    azimuth_deg: np.ndarray
    max_peaks: int

    def __len__(self) -> int: ...
    def __getitem__(self, i: int) -> dict: ...
    def close(self) -> None: ...


__all__ = ["TorchSamples", "LABEL_MAP", "pad"]

#: the label map of an image, stored beside it: ``label_map/<method>/<name>``, int
#: arrays (R, E, A) of the image's shape (issue 35 item 4)
LABEL_MAP = ("object", "order")


def pad(a: np.ndarray, n: int, fill: float) -> tuple[np.ndarray, int]:
    """`a` (N, ...) cut or padded with `fill` to (n, ...) along its first axis, and
    the number of real rows, min(N, n)."""
    a = np.asarray(a)
    k = min(a.shape[0], n)
    out = np.full((n, *a.shape[1:]), fill, a.dtype)
    out[:k] = a[:k]
    return out, k


def pose_vector(pose: dict) -> np.ndarray:
    """A stored pose (``position_m`` world m, ``yaw_deg``, ``pitch_deg``,
    ``roll_deg``) as (6,) float32: x, y, z (m), yaw, pitch, roll (rad)."""
    angles = np.deg2rad([pose["yaw_deg"], pose["pitch_deg"], pose["roll_deg"]])
    return np.concatenate([np.asarray(pose["position_m"], float), angles]).astype(np.float32)


class TorchSamples:
    """A dataset folder as fixed-shape samples (see the module docstring).

    Parameters
    ----------
    reader : DatasetReader
        The dataset (our shards or CHIRP shards).
    method : str
        The image (and its peaks and label map) of our shards: a name of
        ``[store] images``.
    mask : bool
        Add the range gate to ``image`` as a second channel: 1.0 at the range bins
        the gate kept, 0.0 at those it left out (which hold the floor).
    max_paths : int
        Truth paths per sample, padded to this count (of more, the strongest).
    max_points : int or None
        LiDAR points per sample of CHIRP shards, padded (or cut) to this count;
        None: no LiDAR.
    """

    def __init__(
        self,
        reader: Samples,
        *,
        method: str = "das",
        mask: bool = False,
        max_paths: int = 256,
        max_points: int | None = None,
    ) -> None:
        self.reader, self.method, self.mask = reader, method, mask
        self.max_paths, self.max_points = int(max_paths), max_points
        self.chirp = reader.manifest.get("shard_format") == "chirp"
        if not self.chirp and reader.manifest.get("schema_version", 0) < 3:
            raise InputError(
                "shards of schema version < 3 have images whose range axis follows the "
                "speed of sound (not batchable); regenerate the dataset",
                file=reader.folder,
            )
        if not self.chirp:  # read once; no shard left open for DataLoader's workers
            self.range_m, self.max_peaks = reader.range_m, reader.max_peaks
            self.elevation_rad = np.deg2rad(reader.elevation_deg)
            self.azimuth_rad = np.deg2rad(reader.azimuth_deg)
            reader.close()

    def __len__(self) -> int:
        """Number of samples."""
        return len(self.reader)

    def __getitem__(self, i: int) -> dict:
        """Sample `i` as a dict of fixed-shape arrays (docs/dataset-format.md)."""
        s = self.reader[i]
        p = s["params"]
        out: dict = {
            "index": int(p["index"]),
            "pose": pose_vector(p["pose"]),
            "speed_of_sound_m_s": np.float32(p["speed_of_sound_m_s"]),
        }
        out.update(self._paths(s))
        if self.chirp:
            out["raw"] = np.asarray(s["raw"], np.float32)
            if self.max_points is not None:
                points = s.get("lidar/points_m", np.zeros((0, 3), np.float32))
                out["lidar_points_m"], out["n_lidar_points"] = pad(points, self.max_points, 0)
        else:
            out.update(self._image(s, i))
            if "raw" in s:  # [store] raw: (M, T), one M and T in a dataset (its spec's check)
                out["raw"] = np.asarray(s["raw"], np.float32)
        return out

    def _paths(self, s: dict) -> dict:
        """The truth paths: every numeric ``labels/<name>`` array with one row per
        path (as many as ``labels/order``), padded to ``max_paths`` rows (0.0, or -1
        for integers), and the number of real rows; of more paths than that, the
        ``max_paths`` strongest (``labels/amplitude``), in their stored order."""
        if "labels/order" not in s:
            return {}
        count = len(s["labels/order"])
        rows = np.arange(count)
        if count > self.max_paths and "labels/amplitude" in s:  # the strongest, in order
            strength = np.abs(s["labels/amplitude"])
            rows = np.sort(np.argsort(-strength, kind="stable")[: self.max_paths])
        paths = {}
        for key, a in s.items():
            name = key.removeprefix("labels/")
            if name == key or not np.issubdtype(a.dtype, np.number) or a.ndim == 0:
                continue
            if name == "depth_m" or a.shape[0] != count:
                continue
            wide = np.int64 if np.issubdtype(a.dtype, np.integer) else np.float32
            fill = -1 if wide is np.int64 else 0
            paths[name], _ = pad(a[rows].astype(wide), self.max_paths, fill)
        return {"paths": paths, "n_paths": min(count, self.max_paths)}

    def _image(self, s: dict, i: int) -> dict:
        m = self.method
        if f"image/{m}" not in s:
            raise KeyError(f"sample {i} has no image/{m}; stored: {sorted(s)}")
        img = np.asarray(s[f"image/{m}"], np.float32)[None]
        kept = np.zeros(img.shape[1], bool)
        kept[s["range_index"]] = True
        if self.mask:
            gate = np.broadcast_to(kept[:, None, None], img.shape[1:]).astype(np.float32)
            img = np.concatenate([img, gate[None]])
        out = {"image": img, "kept": kept}
        cells = np.asarray(s[f"peaks/{m}/index"], np.int64).reshape(-1, 3)
        table = np.stack(
            [
                self.range_m[cells[:, 0]],
                self.elevation_rad[cells[:, 1]],
                self.azimuth_rad[cells[:, 2]],
                s[f"peaks/{m}/level_db"],
            ],
            axis=-1,
        ).astype(np.float32)
        out["peaks"], out["n_peaks"] = pad(table, self.max_peaks, 0)
        out["peak_index"], _ = pad(cells, self.max_peaks, -1)
        labels = {k: s[f"label_map/{m}/{k}"] for k in LABEL_MAP if f"label_map/{m}/{k}" in s}
        if labels:
            out["labels"] = {k: np.asarray(v, np.int64) for k, v in labels.items()}
        if "labels/depth_m" in s:
            out["depth_m"] = np.asarray(s["labels/depth_m"], np.float32)
        return out
