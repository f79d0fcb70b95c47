"""Sensor noise at a stated SNR (eq. 2 of the paper).

Definition used in every experiment: the signal power is the noise-free energy of
the recording, averaged over microphones, divided by the length of one call in
samples, i.e. the mean power of the echoes while one call lasts::

    P_s = sum_{m,t} s_m(t)^2 / (M * L)       L = call duration * fs
    SNR = 10 log10(P_s / sigma^2)

For a single echo this is the echo's own mean power, independent of the length of
the recording window and of where the echo lies in it.  The noise is white and
Gaussian with variance sigma^2, independent between microphones and measurements.
"""

from __future__ import annotations

import threading

import numpy as np

from acousim.synth.normal import standard_normal

__all__ = ["signal_power", "noise_sigma", "add_noise", "NoiseDraw"]


def signal_power(clean: np.ndarray, call_samples: int) -> float:
    """P_s of a noise-free (M, T) recording (see the module docstring)."""
    if call_samples <= 0:
        raise ValueError(f"call_samples must be positive, got {call_samples}")
    return float(np.sum(np.square(clean)) / (clean.shape[-2] * call_samples))


def noise_sigma(clean: np.ndarray, snr_db: float, call_samples: int) -> float:
    """Noise standard deviation that gives `snr_db` for this signal."""
    return float(np.sqrt(signal_power(clean, call_samples) / 10 ** (snr_db / 10)))


class NoiseDraw:
    """``rng.standard_normal(shape)`` drawn in a background thread, started now, while
    the caller renders (:func:`acousim.synth.normal.standard_normal`, which releases
    the GIL while it fills the array, as numpy's generators do): the same values as
    drawing them later, off the renderer's path."""

    def __init__(self, rng: np.random.Generator, shape: tuple[int, ...]) -> None:
        self.shape = tuple(shape)
        self._out: list = []
        self._thread = threading.Thread(target=self._draw, args=(rng,), daemon=True)
        self._thread.start()

    def _draw(self, rng: np.random.Generator) -> None:
        try:
            self._out.append(standard_normal(rng, self.shape))
        except BaseException as error:  # handed to the caller by result()
            self._out.append(error)

    def result(self) -> np.ndarray:
        """The draws (shape), once drawn; the drawing's exception, if it failed."""
        self._thread.join()
        out = self._out[0]
        if isinstance(out, BaseException):
            raise out
        return out


def add_noise(
    clean: np.ndarray,
    sigma: float,
    rng: np.random.Generator,
    n_measurements: int | None = None,
    drawn: NoiseDraw | None = None,
) -> np.ndarray:
    """`clean` (M, T) plus white Gaussian noise; (K, M, T) when `n_measurements` is given.

    `drawn`: the unit normal draws of `rng`, made in advance (:class:`NoiseDraw`) of
    the output's shape; the result is the same as without it.  The draws are
    numpy's ``rng.standard_normal`` (:func:`acousim.synth.normal.standard_normal`).
    """
    shape = clean.shape if n_measurements is None else (n_measurements, *clean.shape)
    if drawn is not None and drawn.shape != shape:
        raise ValueError(f"noise drawn for shape {drawn.shape}, the output is {shape}")
    out = standard_normal(rng, shape) if drawn is None else drawn.result()
    out *= sigma  # in place: the same values as clean + sigma * z, without temporaries
    out += clean
    return out
