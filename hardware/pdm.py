"""1-bit PDM: tick words <-> microphone signals.

Decoding: tick words -> 32 bit planes -> +-1 -> low-pass FIR and decimation by 10 ->
450 kHz per channel.  Two engines compute the same polyphase sum:

``"table"`` (the default where the C kernel is built)
    The words are transposed into one byte stream per channel (8 ticks a byte); the FIR
    is then a sum of table look-ups, one per byte: for every byte position under the
    filter a table holds, for all 256 byte values, the contribution of those 8 ticks to
    8 consecutive outputs (AVX2, float32).  Exact to float32 rounding.
``"fft"`` (numpy only)
    The ten polyphase filters run at the decimated rate, by FFT.

Filters (:data:`FILTERS`): ``"equiripple"`` (default; 157 taps, Parks-McClellan:
0-100 kHz within 0.01 dB, at least 80 dB down from 225 kHz, the output's Nyquist, so
nothing aliases) and ``"rtis"`` (the vendor host's 512-tap Hamming FIR, cut-off 100 kHz:
3.3x the work, and only 53 dB of alias rejection).  Any taps can be given instead.

Encoding (for the emulated sensor): a second-order sigma-delta modulator, its loop
over time in the C kernel (or in numpy, vectorised over channels: the same bits).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal, get_args

import numpy as np
from scipy import fft as sfft
from scipy.signal import firwin, remez, resample_poly

try:
    from hardware import _pdm_kernel
except ImportError:  # built by setup.py; without a C compiler the numpy engine remains
    _pdm_kernel = None

__all__ = [
    "PDM_RATE_HZ",
    "DECIMATION",
    "FILTERS",
    "FilterName",
    "ENGINES",
    "Engine",
    "decimation_filter",
    "unpack_ticks",
    "decode",
    "modulate",
    "pack_ticks",
    "encode",
]

PDM_RATE_HZ = 4.5e6
DECIMATION = 10
#: decimation filter names (checked in :func:`decimation_filter`)
FilterName = Literal["equiripple", "rtis"]
FILTERS: tuple[str, ...] = get_args(FilterName)
#: decoding engines (checked in :func:`decode`); "auto" picks the first available
Engine = Literal["table", "fft", "auto"]
ENGINES = ("table", "fft") if _pdm_kernel is not None else ("fft",)
_ROW_PAD = 257  # table rows per byte position: 256 values + 1 so positions do not alias


@lru_cache(maxsize=8)
def decimation_filter(name: FilterName = "equiripple") -> np.ndarray:
    """Taps (L,) of a named decimation FIR at 4.5 MHz, unit gain at DC.

    ``"equiripple"``: 157 taps, passband 0-100 kHz (ripple < 0.01 dB), stopband from
    225 kHz (> 80 dB).  ``"rtis"``: 512 taps, ``firwin(512, 100 kHz)`` with a Hamming
    window, as the sensor's host software.
    """
    if name == "equiripple":
        h = remez(157, [0, 100e3, 225e3, PDM_RATE_HZ / 2], [1, 0], weight=[1, 6], fs=PDM_RATE_HZ)
        h = h / h.sum()
    elif name == "rtis":
        h = firwin(512, 100e3, fs=PDM_RATE_HZ)
    else:
        raise ValueError(f"unknown decimation filter {name!r}; known: {', '.join(FILTERS)}")
    h.flags.writeable = False
    return h


def unpack_ticks(ticks: np.ndarray) -> np.ndarray:
    """Tick words (n_ticks,) -> bits (n_ticks, 32) uint8 in {0, 1}; column k is channel k."""
    t = np.ascontiguousarray(ticks, dtype="<u4")
    return np.unpackbits(t.view(np.uint8).reshape(-1, 4), axis=1, bitorder="little")


def decode(
    ticks: np.ndarray,
    channels: np.ndarray | None = None,
    fir: np.ndarray | FilterName | None = None,
    decimation: int = DECIMATION,
    engine: Engine = "auto",
) -> np.ndarray:
    """Tick words (N,) -> decimated signals (C, N // decimation), float32.

    Each channel's bits b are read as x = 2 b - 1 (and x = 0 before the first and after
    the last tick) and filtered by `fir` (taps, or a name from :data:`FILTERS`; default
    ``"equiripple"``).  The FIR's group delay ((L - 1) // 2 ticks) is removed: output
    sample n is at tick ``n * decimation``.  `engine` is ``"table"``, ``"fft"`` or
    ``"auto"`` (the table engine where its C kernel is built).
    """
    if fir is None or isinstance(fir, str):
        h = decimation_filter(fir or "equiripple")
    else:
        h = np.asarray(fir, float)
    if h.ndim != 1 or h.size == 0:
        raise ValueError(f"fir must be a name or a 1-D array of taps, got shape {h.shape}")
    if int(decimation) < 1:
        raise ValueError(f"decimation must be a positive integer, got {decimation}")
    if engine == "auto":
        engine = ENGINES[0]
    if engine not in ENGINES:
        raise ValueError(f"unknown or unavailable engine {engine!r}; available: {ENGINES}")
    ticks = np.ascontiguousarray(ticks, dtype="<u4")
    rows = np.arange(32) if channels is None else np.asarray(channels, int)
    if rows.size and (rows.min() < 0 or rows.max() > 31):
        raise ValueError(f"channels must be in 0..31, got {rows.tolist()}")
    if engine == "table":
        return _decode_table(ticks, rows, h, int(decimation))
    return _decode_fft(ticks, rows, h, int(decimation))


def _decode_table(ticks: np.ndarray, rows: np.ndarray, h: np.ndarray, D: int) -> np.ndarray:
    """The table engine; see the module docstring."""
    N = ticks.size
    n_out = N // D
    T, E = _tables(h.tobytes(), D)
    n_pos = T.shape[0]
    n_groups = max(-(-n_out // 8), 1)
    n8 = -(-N // 8)
    stride = max(E + n8, D * (n_groups - 1) + n_pos)
    words = ticks
    if N % 8:  # ticks past the end read as bit 0 (x = -1, corrected below)
        words = np.zeros(n8 * 8, "<u4")
        words[:N] = ticks
    streams = np.zeros((32, stride), np.uint8)
    _pdm_kernel.transpose(words, streams, stride, E)
    out = _aligned_empty((rows.size, n_groups * 8), np.float32)
    _pdm_kernel.lut_fir(
        streams, stride, rows.astype(np.int32), T, n_pos, _ROW_PAD, D, n_groups, out
    )
    y = out[:, :n_out] if n_out % 8 == 0 else np.ascontiguousarray(out[:, :n_out])
    # the tables read every bit as x = 2 b - 1, the padding around the ticks too: give
    # back the taps that fell outside 0 <= tick < N (a few outputs at either end)
    n, value = _edge_correction(h.tobytes(), N, D)
    y[:, n] += value
    return y


def _aligned_empty(shape: tuple[int, ...], dtype: type, align: int = 64) -> np.ndarray:
    """np.empty with its first element on an `align`-byte boundary: the kernel's 32-byte
    rows then never straddle a cache line (a 16-byte aligned table was up to 1.7x slower,
    varying from process to process with where malloc put it)."""
    n = int(np.prod(shape)) * np.dtype(dtype).itemsize
    raw = np.empty(n + align, np.uint8)
    start = -raw.ctypes.data % align
    return raw[start : start + n].view(dtype).reshape(shape)


@lru_cache(maxsize=16)
def _edge_correction(h_bytes: bytes, N: int, D: int) -> tuple[np.ndarray, np.ndarray]:
    """Output indices and, for each, the sum of the taps that read ticks outside 0..N-1."""
    h = np.frombuffer(h_bytes, float)
    L = len(h)
    n_out = N // D
    d = (L - 1) // 2
    # only the first and last few outputs have taps outside the ticks
    first = np.arange(min(n_out, -(-(L - d) // D) + 1))
    n = np.unique(np.concatenate([first, np.arange(max(n_out - (d // D + 2), 0), n_out)]))
    outside = _taps_outside(h, N, D, n)
    keep = outside != 0.0
    return n[keep], outside[keep].astype(np.float32)


def _taps_outside(h: np.ndarray, N: int, D: int, n: np.ndarray) -> np.ndarray:
    """For outputs n, the sum of the taps that read ticks before 0 or from N on (output
    n's tap k reads tick n D + (L - 1) // 2 - k)."""
    L = len(h)
    cum = np.concatenate([[0.0], np.cumsum(h)])
    top = n * D + (L - 1) // 2
    before = cum[L] - cum[np.clip(top + 1, 0, L)]  # k > top: ticks < 0
    after = cum[np.clip(top - N + 1, 0, L)]  # k <= top - N: ticks >= N
    return before + after


@lru_cache(maxsize=8)
def _tables(h_bytes: bytes, D: int) -> tuple[np.ndarray, int]:
    """Look-up tables (Q, 257, 8) float32 for taps h and decimation D, and the number E of
    zero bytes that lead each stream.

    Output 8 g + i of a stream reads bytes D g + q (q < Q) of the stream; bit s of byte
    value v adds ``x h[D i + d + 8 E - 8 q - s]`` with x = 2 bit - 1.  Q is rounded up to a
    multiple of 4 (the kernel reads four positions at a time).
    """
    h = np.frombuffer(h_bytes, float)
    L = h.size
    d = (L - 1) // 2
    E = -(-(L - 1 - d) // 8)
    Q = (7 * D + d + 8 * E) // 8 + 1
    Q = -(-Q // 4) * 4
    q = np.arange(Q)[:, None, None, None]
    s = np.arange(8)[None, None, :, None]
    i = np.arange(8)[None, None, None, :]
    k = D * i + d + 8 * E - 8 * q - s  # (Q, 1, 8, 8)
    taps = np.where((k >= 0) & (k < L), h[np.clip(k, 0, L - 1)], 0.0)
    x = 2.0 * ((np.arange(256)[None, :, None, None] >> s) & 1) - 1  # (1, 256, 8, 1)
    T = _aligned_empty((Q, _ROW_PAD, 8), np.float32)
    T[:, 256:] = 0.0
    T[:, :256] = (x * taps).sum(axis=2)
    T.flags.writeable = False
    return T, E


def _decode_fft(ticks: np.ndarray, rows: np.ndarray, h: np.ndarray, D: int) -> np.ndarray:
    """The numpy engine: polyphase, the D phase filters applied by FFT at the low rate."""
    bits = unpack_ticks(ticks)[:, rows]
    delay = (len(h) - 1) // 2
    n_out = bits.shape[0] // D
    # bits cut into blocks of D after P leading zeros, P making delay + P a multiple of
    # D: output n is then block-convolution output n + (delay + P) / D
    P = (-delay) % D
    shift = (delay + P) // D
    taps = -(-len(h) // D)  # filter length in blocks of D
    n_blocks = shift + n_out + 1
    L = sfft.next_fast_len(n_blocks + taps + 1, real=True)
    # phase-major, FFT along the contiguous last axis: xb[r, c, m] = x[D m + r] of channel c
    C = bits.shape[1]
    xb = np.zeros((D, C, L), np.float32)
    n_in = min(bits.shape[0], n_blocks * D - P)
    flat = np.zeros((n_blocks * D, C), np.float32)
    flat[P : P + n_in] = bits[:n_in]
    xb[:, :, :n_blocks] = flat.reshape(n_blocks, D, C).transpose(1, 2, 0)
    # z[m] = sum_k h[k] x[D m - k]: tap k = D j + s reads block m - j - (s > 0), phase (-s) % D
    G = _phase_filters(np.asarray(h, float).tobytes(), D, L)  # (D, F)
    X = sfft.rfft(xb, axis=-1)  # (D, C, F)
    y01 = sfft.irfft(np.einsum("rcf,rf->cf", X, G), L, axis=-1)[:, shift : shift + n_out].T
    # the bits were read as 0/1, x = 2 b - 1: y = 2 y01 - (sum of the taps that fall
    # on real ticks; outside the recording x is 0, as in a zero-padded convolution)
    valid = h.sum() - _taps_outside(h, bits.shape[0], D, np.arange(n_out))
    return (2 * y01 - valid[:, None]).T.astype(np.float32)


@lru_cache(maxsize=8)
def _phase_filters(h_bytes: bytes, D: int, L: int) -> np.ndarray:
    """Spectra (D, L // 2 + 1) of the D polyphase components of h, each placed on the
    input phase it reads, with the one-block delay of phases s > 0 folded in."""
    h = np.frombuffer(h_bytes, float)
    taps = -(-len(h) // D)
    g = np.zeros(taps * D)
    g[: len(h)] = h
    g = g.reshape(taps, D)
    f = np.arange(L // 2 + 1) / L
    G = np.zeros((D, f.size), np.complex64)  # single precision: the input is bits
    for s_ in range(D):
        G[(-s_) % D] += sfft.rfft(g[:, s_], L) * (np.exp(-2j * np.pi * f) if s_ else 1.0)
    G.flags.writeable = False
    return G


def modulate(x: np.ndarray, engine: str = "auto") -> np.ndarray:
    """Second-order sigma-delta of x (C, N), |x| <= 0.5 recommended -> bits (C, N) in {0, 1}.

    The loop ``y = sign(v2); v1 += x - y; v2 += v1 - y`` runs over time: in the C kernel
    (engine ``"table"``, the default where it is built; a few ns per tick and channel) or
    in numpy, vectorised over channels (``"fft"``, about 3 us per tick).  Both give the
    same bits.
    """
    xs = np.clip(np.asarray(x, float), -1, 1)
    C, N = xs.shape
    if (ENGINES[0] if engine == "auto" else engine) == "table" and N:
        out = np.empty((C, N), np.uint8)
        _pdm_kernel.sigma_delta(np.ascontiguousarray(xs), out, N)
        return out
    v1 = np.zeros(C)
    v2 = np.zeros(C)
    out = np.empty((C, N), np.uint8)
    xt = np.ascontiguousarray(xs.T)
    for n in range(N):
        y = np.where(v2 >= 0, 1.0, -1.0)
        out[:, n] = y > 0
        v1 += xt[n] - y
        v2 += v1 - y
    return out


def pack_ticks(bits: np.ndarray, channels: np.ndarray) -> np.ndarray:
    """Bits (C, N) of the given channels -> tick words (N,) uint32 (other channels 0)."""
    words = np.zeros(bits.shape[1], np.uint32)
    for row, ch in zip(bits, np.asarray(channels, int)):
        words |= row.astype(np.uint32) << np.uint32(ch)
    return words


def encode(
    signals: np.ndarray, channels: np.ndarray, sample_rate_hz: float, full_scale: float
) -> np.ndarray:
    """Signals (C, T) at sample_rate_hz -> tick words at 4.5 MHz (the emulator's path).

    Signals are divided by `full_scale` (so that they stay within the modulator's
    stable range, |x| <= 0.5 recommended) and resampled to the PDM rate.
    """
    up = int(round(PDM_RATE_HZ / sample_rate_hz))
    if abs(up * sample_rate_hz - PDM_RATE_HZ) > 1e-6 * PDM_RATE_HZ:
        raise ValueError(f"sample rate {sample_rate_hz} Hz does not divide 4.5 MHz")
    x = resample_poly(np.asarray(signals, float) / full_scale, up, 1, axis=-1)
    return pack_ticks(modulate(x), channels)
