"""The renderer's last step at complex baseband (``render_rate = "baseband"``).

The full-rate renderer (:func:`acousim.synth.doppler.render_planned`, the static
``render``) writes each gain set's impulses at the sample rate (fractional-delay
kernels), transforms them (R sets x M microphones real FFTs of n points),
multiplies by the sets' filters and transforms back.  The call spans 25-50 kHz of
a 450 kHz sampling: most of those bins are empty.  Here the echoes' sets' spectra
are computed only over the band where their filters carry energy (the bins within
``floor_db`` of the strongest, centred on bin c, half-width B), as a type-1
non-uniform FFT: each impulse at q samples, gain g, becomes the complex gain
``g exp(-2 pi i c q / n)`` spread over W points of a coarse grid of nb >= sigma
2 B points (nb points over the same n samples; a length rich in twos, for its FFTs)
by the "exponential of semicircle" kernel phi; the coarse grid's FFT divided by
phi's Fourier transform is ``sum g exp(-2 pi i (c + k) q / n)`` at bins c + k,
|k| <= B, to the kernel's aliasing error.  The grids, sums and FFTs are in the
render's precision (single with a path response, as the full-rate renderer's
impulses and spectra), one grid per set and microphone in the layout the FFTs read;
the filtered band goes straight into an n-point spectrum per microphone, and one
real inverse FFT per microphone gives the samples.  The direct path (tens of dB
above the echoes: its band cut at their floor would leave its error above theirs)
is summed in time by the callers onto those samples, as the full-rate renderer
sums it (:mod:`acousim.synth.timedomain`: its few paths' filtered calls through the
same fractional-delay weights, no FFT per microphone).

Error against the full-rate renderer, the corridor's echoes (the direct path left
out), W = 4 and sigma = 1.5 (:data:`TAPS`, :data:`OVERSAMPLING`): -62 dB at a -60 dB
band (8 poses of the drive at the `fast` preset, 2 887-3 784 paths: -61.6 to
-62.4 dB; -63 dB on a pose of 3 937 paths at the defaults), -65 dB at -80 dB (the
kernel's limit; W = 6: -84 dB at -80 dB, the full-rate kernel's own error is -81
dB).  CPU time of the step (the gain sets given), the same 8 poses rendered again
and again: 7.2-7.4 ms a pose against 14.8-17.7 before the grids were laid out for
the FFTs and the direct path summed in time, and 11.0-11.8 at the full rate
(docs/physics.md, "Render at baseband").
``tests/acousim/synth/test_baseband.py`` checks it against exact references.
"""

from __future__ import annotations

import threading
from functools import lru_cache

import numpy as np
from scipy import fft as sfft

from processing.base.kernels import optional_kernel

__all__ = [
    "spectra",
    "echo_sets",
    "set_energy",
    "render_band",
    "BasebandGrid",
    "grid",
    "centre",
    "quantized",
    "TAPS",
    "OVERSAMPLING",
]

#: kernel taps per impulse on the coarse grid and the grid's oversampling of the band
#: (docs/physics.md, speed: with the band at -60 dB, the corridor's echoes within
#: -62 to -64 dB of the full-rate renderer's)
TAPS = 4
OVERSAMPLING = 1.5

#: fractions of a coarse sample at which the kernel is tabulated (the nearest is
#: taken: a position error of 1 / (2 TABLE_PHASES) coarse sample)
TABLE_PHASES = 8192


class BasebandGrid:
    """The coarse grid of a render: centre bin c, half-width B (bins of the n-point
    grid), nb coarse points, kernel width W, its table and Fourier transform psi
    (2 B + 1,) at bins -B .. B."""

    def __init__(self, n: int, c: int, half: int, width: int, sigma: float) -> None:
        self.n, self.c, self.half, self.width = n, c, half, width
        self.nb = _grid_length(max(int(np.ceil(sigma * (2 * half + 1))), 2 * width))
        self.beta = _beta(width, self.nb / (2 * half + 1))
        self.table = _table(width, self.beta)
        k = np.arange(-half, half + 1)
        self.psi = _transform(width, self.beta, k / self.nb)
        #: cos and -sin of the centre's turn at every whole sample of the n-point span
        turn = 2 * np.pi * c / n * np.arange(n + 1)
        self.spin = np.stack([np.cos(turn), -np.sin(turn)], axis=1)


def _grid_length(least: int) -> int:
    """The coarse grid's length: the smallest ``2**k f`` (f = 1, 3, 5, 9 or 15) of at
    least `least` points (FFTs of lengths rich in twos: 2 560 points 0.84 ms, 150
    single-precision transforms, against 1.04 ms at 2 500, the next 5-smooth length)."""
    return min(f << max(int(np.ceil(np.log2(least / f))), 0) for f in (1, 3, 5, 9, 15))


def grid(n: int, c: int, half: int, width: int, sigma: float) -> BasebandGrid:
    """The :class:`BasebandGrid` of these sizes (cached: a drive reuses it)."""
    return _grid(int(n), int(c), int(half), int(width), float(sigma))


#: the band's half-width is rounded up to a multiple of this many bins and its
#: centre to a multiple of half of it, so that a drive's poses share their grids
BAND_QUANTUM = 32


def quantized(c: int, half: int, n_bins: int) -> tuple[int, int]:
    """The band (centre bin c, half-width B) widened to the grid of
    :data:`BAND_QUANTUM`, inside bins 0 .. n_bins - 1."""
    q = BAND_QUANTUM
    lo, hi = c - half, c + half
    c = int(np.round(c / (q // 2))) * (q // 2)
    half = int(np.ceil((max(c - lo, hi - c) + 1) / q)) * q
    half = min(half, (n_bins - 1) // 2)
    return min(max(c, half), n_bins - 1 - half), half


@lru_cache(maxsize=16)
def _grid(n: int, c: int, half: int, width: int, sigma: float) -> BasebandGrid:
    return BasebandGrid(n, c, half, width, sigma)


def _beta(width: int, sigma: float) -> float:
    """The kernel's shape parameter for `width` taps at oversampling `sigma` (the
    exponential-of-semicircle kernel's rule: its cut-off at the edge of the aliases)."""
    return float(np.pi * width * (1 - 0.5 / sigma) * 0.98)


def _phi(x: np.ndarray, width: int, beta: float) -> np.ndarray:
    z = 2 * np.asarray(x, float) / width
    inside = np.abs(z) < 1
    out = np.zeros(z.shape)
    out[inside] = np.exp(beta * (np.sqrt(1 - z[inside] ** 2) - 1))
    return out


@lru_cache(maxsize=16)
def _table(width: int, beta: float) -> np.ndarray:
    """Tap weights (TABLE_PHASES + 1, W): tap j of an impulse at fraction f of a
    coarse sample after the tap ``first + W // 2 - 1`` lies at ``j - (W // 2 - 1) - f``."""
    f = np.linspace(0.0, 1.0, TABLE_PHASES + 1)
    offsets = np.arange(width) - (width // 2 - 1)
    return _phi(offsets[None, :] - f[:, None], width, beta)


def _transform(width: int, beta: float, nu: np.ndarray) -> np.ndarray:
    """phi's Fourier transform at `nu` (cycles per coarse sample): Gauss-Legendre
    quadrature over its support (phi is even: a cosine transform)."""
    x, w = np.polynomial.legendre.leggauss(max(64, 8 * width))
    x, w = x * width / 2, w * width / 2
    return (np.cos(2 * np.pi * np.outer(nu, x)) * _phi(x, width, beta)) @ w


def centre(filters: np.ndarray, gains_energy: np.ndarray, floor_db: float) -> tuple[int, int]:
    """The band's centre bin c and half-width B (bins) of the sets' `filters` (R, F)
    weighted by the energy of their gains (R,): every bin within `floor_db` of the
    strongest, inside the n-point real FFT's bins 0 .. F - 1."""
    power = gains_energy @ (np.abs(filters) ** 2)
    on = np.flatnonzero(power >= power.max() * 10 ** (floor_db / 10))
    k0, k1 = int(on[0]), int(on[-1])
    c = (k0 + k1) // 2
    return quantized(c, max(c - k0, k1 - c, 1), filters.shape[1])


def echo_sets(gains: np.ndarray, direct: np.ndarray) -> np.ndarray:
    """Which gain sets of `gains` (M, N, R) are the echoes' (R,) bool: those with no
    gain on the direct path's paths (`direct` (N,) bool; each set is of one group,
    the compression's or the factorisation's: the direct path's sets are zero on the
    echoes' paths, the echoes' on the direct path's)."""
    d = np.flatnonzero(direct)
    return ~np.any(gains[:, d] != 0, axis=(0, 1))


def set_energy(gains: np.ndarray) -> np.ndarray:
    """The energy of each gain set (R,): the sum of squares of `gains` (M, N, R)
    over its microphones and paths (compiled, or numpy)."""
    kernel = optional_kernel("acousim.synth._baseband_kernel", "set_energy")
    if kernel is None:
        flat = gains.reshape(-1, gains.shape[2])
        return np.einsum("ir,ir->r", flat, flat)
    return kernel(np.ascontiguousarray(gains, float))


def spectra(
    q: np.ndarray,
    gains: np.ndarray,
    filters: np.ndarray,
    sets: np.ndarray,
    energy: np.ndarray,
    floor_db: float,
    dtype,
    n: int,
) -> np.ndarray:
    """The spectra (M, F) of an `n`-point real FFT (F = n // 2 + 1; `filters` (R, F):
    the sets' filters on it) of the impulses at q (M, N) samples with the gain sets
    `sets` (R',) of `gains` (M, N, R), of energy `energy` (R,): over the bins within
    `floor_db` of their strongest (:func:`centre`), zero elsewhere
    (:func:`render_band`, in `dtype`, complex64 or complex128).  For the echoes:
    the direct path, tens of dB above them, is summed in time by the callers (a band
    cut at the echoes' floor would leave its error above theirs).  The spectra are
    this thread's buffer (:func:`render_band`): valid until its next render."""
    c, half = centre(filters[sets], energy[sets], floor_db)
    g = grid(n, c, half, TAPS, OVERSAMPLING)
    return render_band(q, gains, filters[sets, c - half : c + half + 1], g, dtype, sets)


def render_band(
    positions: np.ndarray,
    gains: np.ndarray,
    filters: np.ndarray,
    g: BasebandGrid,
    dtype,
    sets: np.ndarray,
) -> np.ndarray:
    """The filtered spectra (M, n // 2 + 1) of the n-point real FFT (n = g.n): at
    bins c - B .. c + B the sets' sum, zero elsewhere.

    positions (M, N): impulses in samples from the buffer's start; gains (M, N, S):
    the sets' gains, of which the sets `sets` (R,) are rendered; filters (R, 2 B +
    1): their filters over those bins; dtype: complex64 or complex128, the coarse
    grids' sums and FFTs and the spectra.  The coarse grids (R, M, nb) are written
    whole by :func:`._baseband_kernel.accumulate` (taps past an end folded onto the
    other), transformed in place in this thread (a simulator renders while it plans
    the next pose) and summed with the filters (divided by the kernel's transform)
    straight into the spectra's rows (:func:`._baseband_kernel.band_products`).  The
    grids and the spectra are this thread's buffers, reused by its next render of
    the same shapes (the spectra returned are one: read them before)."""
    M = positions.shape[0]
    R, W = sets.size, g.width
    real = np.float32 if np.dtype(dtype) == np.complex64 else np.float64
    coarse = _buffer("coarse", (R, M, 2 * g.nb), real)  # each grid's real, imaginary parts
    grid_args = np.array([2 * np.pi * g.c / g.n, g.nb / g.n, -(W // 2 - 1)], float)
    q = np.ascontiguousarray(positions, float)
    gains = np.ascontiguousarray(gains, float)
    sets = np.ascontiguousarray(sets, np.int64)
    kernel = optional_kernel("acousim.synth._baseband_kernel", "accumulate")
    (kernel or _accumulate_numpy)(q, gains, sets, g.table, g.spin, grid_args, coarse)
    spectra = sfft.fft(coarse.view(dtype), axis=-1, workers=1, overwrite_x=True)
    out = _buffer("spectra", (M, g.n // 2 + 1), dtype)
    filt = np.divide(filters, g.psi).astype(dtype)
    products = optional_kernel("acousim.synth._baseband_kernel", "band_products")
    (products or _band_products_numpy)(spectra, filt, g.half, g.c - g.half, out)
    return out


_BUFFERS = threading.local()


def _buffer(name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
    """This thread's buffer `name` of `shape` and `dtype` (contents undefined), kept
    for the next render of the same shape: its memory mapped once (a fresh buffer
    of megabytes costs its page faults on every render where the process does not
    keep freed memory, :func:`acousim.process.configure`)."""
    held = _BUFFERS.__dict__.get(name)
    if held is None or held.shape != shape or held.dtype != dtype:
        held = np.empty(shape, dtype)
        setattr(_BUFFERS, name, held)
    return held


def _accumulate_numpy(q, gains, sets, table, spin, grid, out) -> None:
    """:func:`._baseband_kernel.accumulate` without numba (the same sums, the turn
    ``exp(-i turn q)`` evaluated directly)."""
    turn, scale, offset = grid[0], grid[1], int(grid[2])
    view = out.view(np.complex64 if out.dtype == np.float32 else complex)  # (R, M, nb)
    nb, W, P = view.shape[2], table.shape[1], table.shape[0] - 1
    u = q * scale
    i0 = np.floor(u)
    w = table[np.rint((u - i0) * P).astype(np.intp)] * np.exp(-1j * turn * q)[..., None]
    idx = (i0.astype(np.int64)[..., None] + offset + np.arange(W)) % nb  # (M, N, W)
    view[...] = 0
    for r, s in enumerate(sets):
        for m in range(q.shape[0]):
            np.add.at(view[r, m], idx[m].ravel(), (w[m] * gains[m, :, s, None]).ravel())


def _band_products_numpy(spectra, filters, half: int, b0: int, out) -> None:
    """:func:`._baseband_kernel.band_products` without numba."""
    nb = spectra.shape[2]
    k = np.arange(-half, half + 1) % nb
    out[...] = 0
    out[:, b0 : b0 + k.size] = np.einsum("rmk,rk->mk", spectra[:, :, k], filters)
