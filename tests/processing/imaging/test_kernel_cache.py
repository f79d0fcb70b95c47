"""The parallel broadband kernels give the same bytes freshly compiled and loaded
from numba's cache (a fresh install's first run against every later run)."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("numba")

# Runs every parallel kernel of processing.imaging.broadband.kernel on seeded inputs
# (each method family: plain DAS by spectrum, DAS-CF and DMAS far field, near field),
# saves the outputs and prints numba's cache hits and misses.
_RUN = r"""
import json, sys
import numpy as np
from processing.imaging.broadband import kernel as k

rng = np.random.default_rng(7)
K, M, G, R, D, U, T = 1, 30, 40, 32, 4, 8, 4
out = {}
Xr, Xi = rng.standard_normal((2, K, M, 256)).astype(np.float32)
d = rng.uniform(-1e-4, 1e-4, (G, M))
beams = np.empty((K, G, 250), np.complex64)
k.far_das_spectrum(Xr, Xi, d, 40e3, 200.0, beams)
out["spectrum"] = beams
zr, zi = rng.standard_normal((2, K, M, U, 300)).astype(np.float32)
q, ph = rng.integers(0, 100, (G, M, T)), rng.integers(0, U, (G, M, T))
w = rng.standard_normal((G, M, T)) + 1j * rng.standard_normal((G, M, T))
none = np.zeros((1, 1, 1, 1), np.float32)
for order, cf, rr, ri in ((1, True, none, none), (2, False, zr, zi)):
    far = np.empty((R, G))
    k.far_field(zr, zi, rr, ri, q, ph, w, order, cf, 435.0, D, far)
    out[f"far_{order}_{cf}"] = far
zf = rng.standard_normal((K, M, 4000)) + 1j * rng.standard_normal((K, M, 4000))
u = rng.standard_normal((G, 3))
u /= np.linalg.norm(u, axis=1, keepdims=True)
pos = rng.uniform(-0.01, 0.01, (M, 3))
for order, cf in ((1, True), (3, False)):
    near = np.empty((R, G))
    k.near_field(zf, zf, u, pos, np.zeros(3), 0.5, 0.004, 100.0, 450e3, 50e3, 343.0,
                 order, cf, 4060.0, D, near)
    out[f"near_{order}_{cf}"] = near
np.savez(sys.argv[1], **out)
kernels = (k.far_das_spectrum, k.far_field, k.near_field)
print(json.dumps({"hits": sum(sum(f.stats.cache_hits.values()) for f in kernels),
                  "misses": sum(sum(f.stats.cache_misses.values()) for f in kernels)}))
"""


def _run(tmp_path, name):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    result = tmp_path / f"{name}.npz"
    done = subprocess.run(
        [sys.executable, "-c", _RUN, str(result)], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1]), np.load(result)


def test_fresh_compile_and_cache_load_give_the_same_bytes(tmp_path):
    fresh_stats, fresh = _run(tmp_path, "fresh")
    cached_stats, cached = _run(tmp_path, "cached")
    assert fresh_stats["misses"] > 0 and fresh_stats["hits"] == 0  # compiled here
    assert cached_stats["hits"] > 0 and cached_stats["misses"] == 0  # loaded
    assert sorted(fresh) == sorted(cached)
    for name in fresh:
        assert np.isfinite(fresh[name]).all() and np.abs(fresh[name]).max() > 0, name
        assert fresh[name].tobytes() == cached[name].tobytes(), name
