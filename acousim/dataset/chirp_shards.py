"""Dataset shards as CHIRP files (``[dataset] format = "chirp"``, docs/dataset-format.md).

Each shard is one CHIRP file (:func:`processing.write_chirp`) holding its samples as
captures: the microphone signals, the ground truth and, for scenes with a
``[sensor.lidar]``, the LiDAR scans; each capture's sample parameters (as in the
sidecar) are in its metadata, ``sample``. CHIRP holds one capture length, so every
sample is simulated :func:`capture_samples` long: what the farthest echo needs in the
slowest air the spec can draw. The ``[store]`` table does not apply.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from pathlib import Path

import processing as P
from acousim.core.air import speed_of_sound
from acousim.dataset.samples import _scene, simulate_sample
from acousim.dataset.spec import DatasetSpec

__all__ = ["write_chirp_shard", "capture_samples"]


def _coldest(spec: DatasetSpec, name: str, default: float) -> float:
    """The lowest value of a randomized air condition the spec can draw."""
    d = spec.randomize.get(name)
    if d is None:
        return default
    if d.kind == "uniform":
        return max(min(d.a, d.b), d.lo)
    return d.a if d.kind == "constant" else d.lo


def capture_samples(spec: DatasetSpec, *, max_range_m: float | None = None) -> int:
    """Samples per capture of every sample of the spec (see the module docstring):
    the round trip to each scene's ``max_range_m`` (or to `max_range_m`, m, when
    given) in the slowest air the spec can draw, plus the call."""

    n = 0
    for choice in spec.scenes:
        scene = _scene(str(choice.file))
        env = scene.environment
        c = speed_of_sound(
            _coldest(spec, "temperature_c", env.temperature_c),
            _coldest(spec, "humidity_percent", env.humidity_percent),
            env.pressure_kpa,
        )
        reach = scene.simulation.max_range_m if max_range_m is None else max_range_m
        sensor = scene.sensor  # a rig's scene: the sonar the samples are of
        if scene.rig is not None:
            sensor = next(s.sensor for s in scene.rig.sonars if s.name == choice.sensor)
        t = 2 * reach / c + sensor.call.duration_s
        n = max(n, math.ceil(t * sensor.sample_rate_hz))
    return n


def write_chirp_shard(spec: DatasetSpec, k: int, lo: int, hi: int, final: Path):
    """Samples lo..hi-1 as the CHIRP file `final`: (records, sha256, bytes)."""

    n = capture_samples(spec)
    recs, records = [], []
    for i in range(lo, hi):
        rec, params, _scene, _pose = simulate_sample(spec, i, n_samples=n)
        params = {**params, "speed_of_sound_m_s": rec.speed_of_sound_m_s, "array": rec.array.name}
        recs.append(dataclasses.replace(rec, metadata={**rec.metadata, "sample": params}))
        records.append({**params, "shard": k, "offset": i - lo})
    P.write_chirp(final, recs, compression=spec.compression)
    data = final.read_bytes()
    return records, hashlib.sha256(data).hexdigest(), len(data)
