"""The render without a path response in single precision: echoes on whole samples
(where every fractional-delay kernel is a unit impulse) are the band-limited call
shifted and scaled, written here sample by sample in float64; single precision keeps
the rendered signals within -120 dB of that (float32 rounding: about -135 dB)."""

import numpy as np
import pytest

import processing as P
from acousim.core.echoes import Echoes
from acousim.synth import render

FS, C = 450e3, 343.0


@pytest.mark.parametrize("interpolator", ["sinc", "lagrange", "nearest"])
def test_echoes_on_whole_samples_are_the_call_shifted_within_float32_rounding(interpolator):
    rng = np.random.default_rng(3)
    M, N, T = 4, 9, 9000
    k = rng.integers(200, 7000, size=(M, N))  # delays in whole samples
    gain = rng.uniform(-1.0, 1.0, size=(M, N)) * 10.0 ** rng.uniform(-3, 0, size=(M, N))
    delay = k / FS
    echoes = Echoes(delay, gain, delay * C, np.ones(N, int))
    wf = P.rtis_call("default_25_50")
    y = render(echoes, wf, FS, T, interpolator=interpolator)
    call, start = wf.band_limited(FS)  # sample i of the call is at i + start
    ref = np.zeros((M, T))
    for m in range(M):
        for n in range(N):
            first = k[m, n] + start
            lo, hi = max(first, 0), min(first + call.size, T)
            ref[m, lo:hi] += gain[m, n] * call[lo - first : hi - first]
    err_db = 10 * np.log10(np.sum((y - ref) ** 2) / np.sum(ref**2))
    assert err_db < -120
