"""The renderer's last step at complex baseband (``render_rate = "baseband"``).

The full-rate renderer (:func:`acousim.synth.doppler.render_planned`, the static
``render``) writes each gain set's impulses at the sample rate (fractional-delay
kernels), transforms them (R sets x M microphones real FFTs of n points),
multiplies by the sets' filters and transforms back.  The call spans 25-50 kHz of
a 450 kHz sampling: most of those bins are empty.  Here the echoes' sets' spectra
are computed only over the band where their filters carry energy (the bins within
``floor_db`` of the strongest, centred on bin c, half-width B), as a type-1
non-uniform FFT: each impulse at q samples, gain g, becomes the complex gain
``g exp(-2 pi i c q / n)`` spread over W points of a coarse grid of nb = sigma 2 B
points (nb points over the same n samples) by the "exponential of semicircle"
kernel phi; the coarse grid's FFT divided by phi's Fourier transform is
``sum g exp(-2 pi i (c + k) q / n)`` at bins c + k, |k| <= B, to the kernel's
aliasing error.  The filtered band goes into an n-point spectrum per microphone
and one real inverse FFT per microphone gives the samples.  The direct path (tens
of dB above the echoes: its band cut at their floor would leave its error above
theirs) is the full-rate renderer's: its impulses at the sample rate, one real FFT
per microphone (one path: a set or two).

Error against the full-rate renderer, the corridor's echoes (a pose of 3 937
paths, the direct path left out), W = 4 and sigma = 1.5 (:data:`TAPS`,
:data:`OVERSAMPLING`): -63 dB at a -60 dB band, -65 dB at -80 dB (the kernel's
limit; W = 6: -84 dB at -80 dB, the full-rate kernel's own error is -81 dB).
``tests/acousim/synth/test_baseband.py`` checks it against exact references.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import fft as sfft

from processing.base.kernels import optional_kernel

__all__ = [
    "spectra",
    "render_band",
    "direct_spectra",
    "BasebandGrid",
    "grid",
    "centre",
    "quantized",
    "TAPS",
    "OVERSAMPLING",
]

#: kernel taps per impulse on the coarse grid and the grid's oversampling of the band
#: (docs/physics.md, speed: with the band at -60 dB, the corridor's echoes within
#: -63 to -66 dB of the full-rate renderer's)
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
        self.nb = sfft.next_fast_len(max(int(np.ceil(sigma * (2 * half + 1))), 2 * width))
        self.beta = _beta(width, self.nb / (2 * half + 1))
        self.table = _table(width, self.beta)
        k = np.arange(-half, half + 1)
        self.psi = _transform(width, self.beta, k / self.nb)
        #: cos and -sin of the centre's turn at every whole sample of the n-point span
        turn = 2 * np.pi * c / n * np.arange(n + 1)
        self.spin = np.stack([np.cos(turn), -np.sin(turn)], axis=1)


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


def spectra(
    q: np.ndarray,
    gains: np.ndarray,
    filters: np.ndarray,
    direct: np.ndarray,
    floor_db: float,
    dtype,
    kernel: tuple[np.ndarray, int],
    n: int,
) -> np.ndarray:
    """Impulses at q (M, N) samples with the gain sets (M, N, S) and their filters
    (S, F) of an `n`-point real FFT (F = n // 2 + 1), their spectra (M, F): the
    echoes' sets over the bins within `floor_db` of their strongest
    (:func:`render_band`); the direct path's (`direct` (N,): its paths, tens of dB
    above the echoes: a band cut at the echoes' floor would leave its error above
    theirs) as the full-rate renderer makes it (`kernel`: its table and taps,
    :func:`direct_spectra`)."""
    M, F = q.shape[0], filters.shape[1]
    spec = np.zeros((M, F), dtype)
    energy = np.einsum("mnr,mnr->r", gains, gains)
    echo_sets = np.ones(energy.size, bool)
    if direct.any():
        d = np.flatnonzero(direct)
        # each set is of one group (the compression's, the factorisation's)
        echo_sets = energy > np.einsum("mnr,mnr->r", gains[:, d], gains[:, d])
        g = gains[:, d][:, :, ~echo_sets]
        spec += direct_spectra(q[:, d], g, filters[~echo_sets], n, *kernel, dtype)
    if echo_sets.any():
        sets = np.flatnonzero(echo_sets)
        c, half = centre(filters[sets], energy[sets], floor_db)
        g = grid(n, c, half, TAPS, OVERSAMPLING)
        bins = slice(c - half, c + half + 1)
        spec[:, bins] += render_band(q, gains, filters[sets, bins], g, 0, dtype, sets)
    return spec


def direct_spectra(
    q: np.ndarray,
    gains: np.ndarray,
    filters: np.ndarray,
    n: int,
    table: np.ndarray,
    taps: int,
    dtype=complex,
) -> np.ndarray:
    """Spectra (M, F) of a few impulses (the direct path) at q (M, N) samples, gains
    (M, N, R), through the filters (R, F) of the n-point real FFT, as the full-rate
    renderer makes them: each impulse its fractional-delay kernel (`table` (P + 1,
    2 taps): the weights at P + 1 fractions, :func:`acousim.synth.render._kernel_table`)
    at the sample rate, one real FFT per path and microphone (in the precision of
    `dtype`, complex64 or complex128, as the full-rate renderer's), times the sum of
    the filters weighted by the path's gains (a path's sets share its impulses)."""
    M, N = q.shape
    n0 = np.floor(q)
    w = table[np.rint((q - n0) * (table.shape[0] - 1)).astype(np.intp)]  # (M, N, 2 taps)
    at = (n0.astype(np.int64)[..., None] - taps + 1 + np.arange(2 * taps)) % n
    real = np.float32 if np.dtype(dtype) == np.complex64 else np.float64
    rows = np.broadcast_to(np.arange(M)[:, None], at.shape[::2])
    out = np.zeros((M, filters.shape[1]), dtype)
    on = np.flatnonzero(np.any(filters != 0, axis=0))
    if not on.size:
        return out
    band = slice(on[0], on[-1] + 1)  # the bins the filters reach
    for k in range(N):
        h = np.zeros((M, n), real)
        h[rows, at[:, k]] = w[:, k]  # a kernel's taps fall on distinct samples
        spectrum = sfft.rfft(h, axis=-1, workers=2)[:, band]  # (M, F')
        out[:, band] += spectrum * (gains[:, k] @ filters[:, band])
    return out


def render_band(
    positions: np.ndarray,
    gains: np.ndarray,
    filters: np.ndarray,
    g: BasebandGrid,
    pad: int,
    dtype,
    sets: np.ndarray,
) -> np.ndarray:
    """The filtered spectra (M, 2 B + 1) at bins c - B .. c + B of the n-point grid.

    positions (M, N): impulses in samples from the span's start (buffer index pad +
    position); gains (M, N, S): the sets' gains, of which the sets `sets` (R,) are
    rendered; filters (R, 2 B + 1): their filters over those bins; dtype: complex64
    or complex128 for the coarse FFT."""
    M, N = positions.shape
    R, W = sets.size, g.width
    q = np.ascontiguousarray(positions + pad, float)  # samples from the buffer's start
    turn, scale = 2 * np.pi * g.c / g.n, g.nb / g.n
    # the coarse buffer has W points either side, folded back afterwards (circular)
    buf = np.zeros((M, g.nb + 2 * W, R, 2))  # the sets' real and imaginary parts innermost
    kernel = optional_kernel("acousim.synth._baseband_kernel", "accumulate")
    gains = np.ascontiguousarray(gains, float)
    args = (q, gains, sets, g.table, g.spin, np.array([turn, scale, W - (W // 2 - 1)], float))
    (kernel or _accumulate_numpy)(*args, buf)
    buf = np.moveaxis(buf.view(complex)[..., 0], 2, 0)  # (R, M, nb + 2 W)
    coarse = buf[:, :, W : W + g.nb].astype(dtype)
    coarse[:, :, :W] += buf[:, :, W + g.nb :]
    coarse[:, :, -W:] += buf[:, :, :W]
    spectra = sfft.fft(coarse, axis=-1, workers=2)  # (R, M, nb)
    k = np.arange(-g.half, g.half + 1) % g.nb
    out = np.zeros((M, k.size), spectra.dtype)
    for r in range(R):
        out += spectra[r][:, k] * filters[r]
    out /= g.psi
    return out


def _accumulate_numpy(q, gains, sets, table, spin, grid, out) -> None:
    """:func:`._baseband_kernel.accumulate` without numba (the same sums)."""
    turn, scale, offset = grid[0], grid[1], int(grid[2])
    gains = gains[:, :, sets]
    M, N, R = gains.shape
    P, W = table.shape[0] - 1, table.shape[1]
    u = q * scale
    i0 = np.floor(u)
    w = table[np.rint((u - i0) * P).astype(np.intp)] * np.exp(-1j * turn * q)[..., None]
    idx = i0.astype(np.int64)[..., None] + offset + np.arange(W)  # (M, N, W)
    view = out.view(complex)[..., 0]  # (M, B, R)
    for r in range(R):
        for m in range(M):
            np.add.at(view[m, :, r], idx[m].ravel(), (w[m] * gains[m, :, r, None]).ravel())
