"""The compiled mean squares of the echoes' noise level
(:func:`acousim.synth._signal_kernel.mean_squares`) against numpy's own."""

import numpy as np
import pytest


@pytest.mark.parametrize("M", [1, 3, 7, 8, 9, 16, 30, 64, 127, 128])
def test_mean_squares_are_numpys_bits(M):
    """numpy's mean over the microphones of the echoes' columns (its copy of them:
    a contiguous, pairwise sum), bit for bit, C or Fortran layout."""
    kernel = pytest.importorskip("acousim.synth._signal_kernel")
    rng = np.random.default_rng(M)
    gain = rng.standard_normal((M, 257)) * rng.uniform(0, 1e3, (M, 257))
    echo = rng.random(257) > 0.2
    ref = np.mean(gain[:, echo] ** 2, axis=0)
    for g in (gain, np.asfortranarray(gain)):
        out = np.empty(257)
        kernel.mean_squares(g, out)
        assert out[echo].tobytes() == ref.tobytes()


def test_echo_power_without_the_kernel_is_numpys(monkeypatch):
    from acousim.synth import signal_model

    rng = np.random.default_rng(0)
    gain = rng.standard_normal((30, 100))
    echo = rng.random(100) > 0.5
    with_kernel = signal_model._mean_squares(gain, echo)
    monkeypatch.setattr(signal_model, "optional_kernel", lambda *a: None)
    plain = signal_model._mean_squares(gain, echo)
    np.testing.assert_array_equal(plain, np.mean(gain[:, echo] ** 2, axis=0))
    np.testing.assert_array_equal(with_kernel, plain)
