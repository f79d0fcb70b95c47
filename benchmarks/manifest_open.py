"""Opening a dataset of many samples: ``DatasetReader(folder)`` on a synthetic
manifest.json of N samples (the shards need not exist to open), in the form that
listed every sample's parameters (``sample_table``, about 1 kB a sample, indent 1)
and in the form without them. Each open in a fresh process: its wall time and peak
memory (ru_maxrss), the two forms in turn, the median of each.

    python -m benchmarks.manifest_open [N] [ROUNDS]
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

#: a sample's parameters as the corridor's spec draws them (the size that matters)
RECORD = {
    "array": "urtis_v1",
    "conditions": {
        "humidity_percent": 72.41320672377572,
        "mount_pitch_deg": 0.4898420501851982,
        "mount_shift_m": [0.0035688700816006074, 0.0010541424899789857, -0.0093046804470],
        "mount_yaw_deg": -0.6204748998199404,
        "reflection_scale": 0.801053060913115,
        "snr_db": 34.63685255148299,
        "temperature_c": 26.956041431280696,
    },
    "emission_index": 0,
    "emitters": ["sensor"],
    "frequency_hz": 28125.000000000004,
    "noise_seed": 2326818151458274759,
    "object_names": ["corridor/plaster"],
    "pose": {
        "pitch_deg": 0.4898420501851982,
        "position_m": [16.20481038704917, -0.2740563081418478, 0.4331095233468227],
        "roll_deg": 0.0,
        "yaw_deg": 4.338837154614563,
    },
    "range_step_m": 0.006,
    "sample_rate_hz": 450000.0,
    "scene": "../scenes/corridor.toml",
    "scene_index": 0,
    "speed_of_sound_m_s": 347.1532186004227,
}

OPEN = """
import resource, sys, time
t = time.perf_counter()
from acousim.dataset import DatasetReader
t0 = time.perf_counter()
r = DatasetReader(sys.argv[1], verify=False)
print(time.perf_counter() - t0, len(r), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def write(folder: Path, n: int, size: int, table: bool) -> int:
    """A manifest of `n` samples in shards of `size` at `folder`; its bytes."""
    folder.mkdir()
    shards = -(-n // size)
    m = {
        "schema": "acousim.dataset",
        "schema_version": 3,
        "samples": n,
        "shard_size": size,
        "shard_format": "acousim",
        "shards": [
            {
                "file": f"shard_{k:05d}.h5",
                "sha256": "0" * 64,
                "bytes": 1,
                "samples": min(size, n - k * size),
            }
            for k in range(shards)
        ],
    }
    path = folder / "manifest.json"
    with path.open("w") as f:
        if not table:
            json.dump(m, f, indent=1, sort_keys=True)
            return path.stat().st_size
        text = json.dumps(m, indent=1, sort_keys=True)  # ends with "\n}"
        f.write(text[: -len("\n}")] + ',\n "sample_table": [\n')
        for i in range(n):
            rec = {**RECORD, "index": i, "shard": i // size, "offset": i % size}
            f.write((",\n" if i else "") + json.dumps(rec, indent=1, sort_keys=True))
        f.write("\n]\n}")
    return path.stat().st_size


def main(n: int = 1_000_000, rounds: int = 3) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        forms = {"sample_table": Path(tmp) / "old", "shards only": Path(tmp) / "new"}
        sizes = {k: write(p, n, 64, k == "sample_table") for k, p in forms.items()}
        runs: dict[str, list[tuple[float, float]]] = {k: [] for k in forms}
        for _ in range(rounds):
            for k, p in forms.items():
                out = subprocess.run(
                    [sys.executable, "-c", OPEN, str(p)], capture_output=True, text=True
                )
                if out.returncode:
                    raise SystemExit(f"{k}: {out.stderr}")
                s, count, rss = out.stdout.split()
                assert int(count) == n
                runs[k].append((float(s), float(rss)))
        for k in forms:
            t = statistics.median(r[0] for r in runs[k])
            m = statistics.median(r[1] for r in runs[k])
            print(
                f"{k:13s} {n} samples: {sizes[k] / 1e6:8.1f} MB, open {t:7.3f} s, peak {m:7.0f} MB"
            )


if __name__ == "__main__":
    main(*map(int, sys.argv[1:]))
