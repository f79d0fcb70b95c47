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
theirs) is the full-rate renderer's: its impulses convolved with its filters'
impulse responses, in time (it lasts one call).

Error against the full-rate renderer, the corridor's echoes (a pose of 3 937
paths, the direct path left out), W = 4 and sigma = 1.5 (:data:`TAPS`,
:data:`OVERSAMPLING`): -63 dB at a -60 dB band, -65 dB at -80 dB (the kernel's
limit; W = 6: -84 dB at -80 dB, the full-rate kernel's own error is -81 dB).
``tests/test_baseband.py`` checks it against exact references.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import fft as sfft

from processing.kernels import optional_kernel

__all__ = [
    "spectra",
    "render_band",
    "direct_samples",
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
) -> tuple[np.ndarray, np.ndarray | None]:
    """Impulses at q (M, N) samples with the gain sets (M, N, S) and their filters
    (S, F) of an `n`-point real FFT (F = n // 2 + 1): the echoes' sets as spectra (M, F)
    over the bins within `floor_db` of their strongest (:func:`render_band`); the
    direct path's (`direct` (N,): its paths, tens of dB above the echoes: a band cut
    at the echoes' floor would leave its error above theirs) as samples (M, n) of the
    buffer, the full-rate renderer's impulses (`kernel`: its table and taps)
    convolved with its filters' impulse responses (:func:`direct_samples`; None
    without a direct path)."""
    M, F = q.shape[0], filters.shape[1]
    spec = np.zeros((M, F), dtype)
    energy = np.einsum("mnr,mnr->r", gains, gains)
    echo_sets = np.ones(energy.size, bool)
    samples = None
    if direct.any():
        d = np.flatnonzero(direct)
        # each set is of one group (the compression's, the factorisation's)
        echo_sets = energy > np.einsum("mnr,mnr->r", gains[:, d], gains[:, d])
        g = gains[:, d][:, :, ~echo_sets]
        samples = direct_samples(q[:, d], g, filters[~echo_sets], n, *kernel)
    if echo_sets.any():
        sets = np.flatnonzero(echo_sets)
        c, half = centre(filters[sets], energy[sets], floor_db)
        g = grid(n, c, half, TAPS, OVERSAMPLING)
        bins = slice(c - half, c + half + 1)
        spec[:, bins] += render_band(q, gains, filters[sets, bins], g, 0, dtype, sets)
    return spec, samples


#: the direct path's filters' impulse responses are cut where they fall below this
#: of their peak (the rest of the n-point circle holds rounding)
SUPPORT_FLOOR = 1e-12


def direct_samples(
    q: np.ndarray, gains: np.ndarray, filters: np.ndarray, n: int, table: np.ndarray, taps: int
) -> np.ndarray:
    """Samples (M, n) of a few impulses (the direct path) at q (M, N) samples, gains
    (M, N, R), through the filters (R, F): each impulse the full-rate renderer's
    fractional-delay kernel (`table` (P + 1, 2 taps): its weights at P + 1 fractions,
    :func:`acousim.synth.render._kernel_table`) circularly convolved with the
    filters' impulse responses (where above :data:`SUPPORT_FLOOR` of their peak): the
    full-rate renderer's signal without its FFTs of every sample."""
    phases = table.shape[0] - 1
    response = sfft.irfft(filters, n, axis=-1)  # (R, n)
    start, length = _support(np.abs(response).max(axis=0))
    seg = response[:, (start + np.arange(length)) % n]  # (R, L)
    out = np.zeros((q.shape[0], n))
    for m in range(q.shape[0]):
        for k in range(q.shape[1]):
            n0 = np.floor(q[m, k])
            w = table[int(np.rint((q[m, k] - n0) * phases))]  # taps at n0 - taps + 1 ..
            y = np.convolve(gains[m, k] @ seg, w)
            where = (int(n0) - taps + 1 + start + np.arange(y.size)) % n
            out[m, where] += y
    return out


def _support(mag: np.ndarray) -> tuple[int, int]:
    """The shortest arc (start, length) of the circle of `mag` (n,) holding every
    value above SUPPORT_FLOOR of its peak."""
    n = mag.size
    on = np.flatnonzero(mag > SUPPORT_FLOOR * mag.max())
    if on.size == 0:
        return 0, 1
    gaps = np.diff(np.r_[on, on[0] + n])  # from each on-sample to the next
    widest = int(np.argmax(gaps))
    start = int(on[(widest + 1) % on.size])
    return start, n - int(gaps[widest]) + 1


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
