"""1-bit PDM: tick words <-> microphone signals.

Decoding: tick words -> 32 bit planes -> +-1 -> low-pass FIR and decimation by 10
(polyphase: the ten phase filters run at the decimated rate, by FFT) -> 450 kHz per
channel.  The default filter
is the sensor's: 512 taps, cut-off 100 kHz at 4.5 MHz.

Encoding (for the emulated sensor): a second-order sigma-delta modulator, its loop
over time vectorised over channels.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import fft as sfft
from scipy.signal import firwin, resample_poly

__all__ = [
    "PDM_RATE_HZ",
    "DECIMATION",
    "decimation_filter",
    "unpack_ticks",
    "decode",
    "modulate",
    "pack_ticks",
    "encode",
]

PDM_RATE_HZ = 4.5e6
DECIMATION = 10


@lru_cache(maxsize=8)
def decimation_filter(
    taps: int = 512, cutoff_hz: float = 100e3, rate_hz: float = PDM_RATE_HZ
) -> np.ndarray:
    """The low-pass FIR applied before decimation (unit DC gain)."""
    h = firwin(taps, cutoff_hz, fs=rate_hz)
    h.flags.writeable = False
    return h


def unpack_ticks(ticks: np.ndarray) -> np.ndarray:
    """Tick words (n_ticks,) -> bits (n_ticks, 32) uint8 in {0, 1}; column k is channel k."""
    t = np.ascontiguousarray(ticks, dtype="<u4")
    return np.unpackbits(t.view(np.uint8).reshape(-1, 4), axis=1, bitorder="little")


def decode(
    ticks: np.ndarray,
    channels: np.ndarray | None = None,
    fir: np.ndarray | None = None,
    decimation: int = DECIMATION,
) -> np.ndarray:
    """Tick words -> decimated signals (C, n_ticks // decimation), float64.

    Each channel's bits b are read as x = 2 b - 1 and filtered by `fir` (default:
    :func:`decimation_filter`) at the decimated rate only: polyphase, with the
    `decimation` phase filters applied by FFT at the low rate.  The FIR's group delay
    ((taps - 1) / 2 ticks) is removed: output sample n is at tick ``n * decimation``.
    """
    h = decimation_filter() if fir is None else np.asarray(fir, float)
    bits = unpack_ticks(ticks)
    if channels is not None:
        bits = bits[:, np.asarray(channels, int)]
    D = int(decimation)
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
    cum = np.concatenate([[0.0], np.cumsum(h)])
    top = np.arange(n_out) * D + delay  # taps k <= top read ticks >= 0
    bottom = top - bits.shape[0]  # taps k <= bottom read ticks past the end
    valid = cum[np.clip(top + 1, 0, len(h))] - cum[np.clip(bottom + 1, 0, len(h))]
    return (2 * y01 - valid[:, None]).T.astype(np.float64)


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


def modulate(x: np.ndarray) -> np.ndarray:
    """Second-order sigma-delta of x (C, N), |x| <= 0.5 recommended -> bits (C, N) in {0, 1}.

    The loop ``y = sign(v2); v1 += x - y; v2 += v1 - y`` runs over time, vectorised
    over channels (about 3 us per tick: an emulator's speed, not a decoder's).
    """
    xs = np.clip(np.asarray(x, float), -1, 1)
    C, N = xs.shape
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
