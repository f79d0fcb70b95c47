"""The compiled standard normal draws against numpy's: bit equality, the state after,
how often the ziggurat's rare paths ran, and ns per draw.

``python -m benchmarks.normal_draws [--draws 50e6]``: draws
:func:`acousim.synth.normal.standard_normal` and numpy's ``standard_normal`` from the
same seeds over shapes from a single draw to the noise of a corridor pose (30,
18000), until `--draws` draws are compared; each pair must agree bit for bit, leave
the same PCG64 state and give the same next ``rng.random()``.  A twin walk of
numpy's raw PCG64 outputs (``random_raw``) with the same tables counts the attempts
that went to a wedge (accepted or not) and to the tail (and the tail's rejected
pairs), and checks that the draws took exactly the outputs numpy took.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from numba import njit

from acousim.synth.normal import standard_normal, ziggurat_tables

SHAPES = [(30, 18000), (1,), (7, 3, 5), (1000,), (2, 30, 9000), (0,), (123457,)]


@njit(cache=True)
def _walk(raw, n, w, k, f):  # pragma: no cover - compiled
    """Walks the ziggurat of n draws over the outputs `raw`: (outputs taken, wedge
    attempts, wedge rejections, tail draws, tail pairs rejected); taken > len(raw)
    when the outputs ran short."""
    counts = np.zeros(5, dtype=np.int64)
    j, mask, r = 0, np.uint64(0x000FFFFFFFFFFFFF), w[255] * 2.0**52
    for _ in range(n):
        while j < raw.shape[0]:
            word = raw[j]
            j += 1
            idx = np.intp(word & np.uint64(0xFF))
            rabs = (word >> np.uint64(9)) & mask
            if rabs < k[idx]:
                break
            x = np.float64(rabs) * w[idx]
            if idx == 0:
                counts[3] += 1
                while j + 2 <= raw.shape[0]:
                    u1 = np.float64(raw[j] >> np.uint64(11)) * 2.0**-53
                    u2 = np.float64(raw[j + 1] >> np.uint64(11)) * 2.0**-53
                    j += 2
                    xx, yy = -(1.0 / r) * np.log1p(-u1), -np.log1p(-u2)
                    if yy + yy > xx * xx:
                        break
                    counts[4] += 1
                break
            counts[1] += 1
            if j >= raw.shape[0]:
                j += 1
                break
            u = np.float64(raw[j] >> np.uint64(11)) * 2.0**-53
            j += 1
            if (f[idx - 1] - f[idx]) * u + f[idx] < np.exp(-0.5 * x * x):
                break
            counts[2] += 1
    counts[0] = j
    return counts


def _one(seed: int, shape: tuple[int, ...], tables) -> tuple[np.ndarray, float, float]:
    """Counts of :func:`_walk` for one seed and shape, after checking the pair; the
    CPU seconds of numpy's draw and of the compiled one."""
    ours, theirs = np.random.default_rng(seed), np.random.default_rng(seed)
    if seed % 2:  # alternating which goes first
        t_ours, a = _timed(standard_normal, ours, shape)
        t_numpy, b = _timed(np.random.Generator.standard_normal, theirs, shape)
    else:
        t_numpy, b = _timed(np.random.Generator.standard_normal, theirs, shape)
        t_ours, a = _timed(standard_normal, ours, shape)
    if a.shape != b.shape or not np.array_equal(a.view(np.uint64), b.view(np.uint64)):
        bad = np.flatnonzero(a.ravel().view(np.uint64) != b.ravel().view(np.uint64))
        raise AssertionError(f"seed {seed} shape {shape}: {bad.size} draws differ, first {bad[:5]}")
    after = theirs.bit_generator.state
    if ours.bit_generator.state != after or ours.random() != theirs.random():
        raise AssertionError(f"seed {seed} shape {shape}: the state after differs")
    n = int(np.prod(shape))
    walked = np.random.default_rng(seed).bit_generator
    counts = _walk(walked.random_raw(int(n * 1.1) + 64), n, *tables)
    walked = np.random.default_rng(seed).bit_generator
    walked.advance(int(counts[0]))
    if walked.state != after:
        raise AssertionError(f"seed {seed} shape {shape}: the walk took other outputs")
    return counts, t_numpy, t_ours


def _timed(draw, rng: np.random.Generator, shape: tuple[int, ...]) -> tuple[float, np.ndarray]:
    """(CPU seconds of this thread, the draws) of ``draw(rng, shape)``."""
    t0 = time.thread_time()
    out = draw(rng, shape)
    return time.thread_time() - t0, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=float, default=50e6, help="draws to compare, at least")
    a = ap.parse_args()
    tables = ziggurat_tables()
    assert tables is not None, "numpy's tables did not check out"
    totals, n, seed, times = np.zeros(5, dtype=np.int64), 0, 0, {}
    while n < a.draws:
        for shape in SHAPES:
            counts, t_numpy, t_ours = _one(seed, shape, tables)
            totals += counts
            n += int(np.prod(shape))
            times.setdefault(shape, []).append((t_numpy, t_ours))
            seed += 1
    size = int(np.prod(SHAPES[0]))
    t = np.array(times[SHAPES[0]][1:])  # the first pair compiles
    print(f"{n} draws over {seed} seeds and {len(SHAPES)} shapes: all equal, states equal")
    print(f"outputs taken {totals[0]} ({totals[0] / n - 1:.5f} extra per draw)")
    print(f"wedge attempts {totals[1]} (rejected {totals[2]}), tail draws {totals[3]}")
    print(f"tail pairs rejected {totals[4]}")
    print(
        f"{SHAPES[0]}: numpy {np.median(t[:, 0]) / size * 1e9:.2f} ns/draw, "
        f"compiled {np.median(t[:, 1]) / size * 1e9:.2f} ns/draw "
        f"(thread CPU, medians of {len(t)}; ratio {np.median(t[:, 1] / t[:, 0]):.3f})"
    )


if __name__ == "__main__":
    main()
