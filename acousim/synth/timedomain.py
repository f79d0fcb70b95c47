"""The full-rate render summed in time (``render_domain = "time"``): for scenes with
few paths.

The frequency-domain render (:mod:`acousim.synth.render`) places every path's
fractional-delay impulses in one buffer per gain set and microphone, transforms the
buffers (an FFT whose length is set by the span the echoes reach: the recording's
range) and multiplies by the sets' filters.  The same sum, term for term, in time:
each gain set's filter applied to the call once (:func:`filtered_calls`: the
filtered call, trimmed to where it has energy), each path's response as its
combination of the sets' filtered calls, and every path's copy at every microphone
passed through the same tabulated fractional-delay weights and added at its delay
(:func:`render_time`).  Cost ``M N 2 taps L`` (L the filtered call's length)
against the frequency domain's ``M (Q + 1)`` FFTs of the span: the time domain wins
for a few paths (the wall, the shoebox: tens), the FFTs for thousands (the
corridor); :func:`prefer_time` estimates both.  The two differ by rounding and by
the filtered calls' tails left out (below :data:`TAIL_ENERGY` of their energy).
A moving pose's Doppler renderer (:mod:`acousim.synth.doppler`) hands over its
compressed gain sets: each copy's call is then its own mix of the sets' filtered
calls.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from functools import cache

import numpy as np
from scipy import fft as sfft

from processing.base.kernels import optional_kernel

__all__ = ["filtered_calls", "trimmed", "render_time", "prefer_time", "TAIL_ENERGY"]

#: the filtered calls' tails left out hold at most this fraction of their energy
#: (-110 dB: the sets' filters, cut at the band's edges and interpolated piecewise
#: linearly, have slowly decaying tails: the shoebox's filtered calls are 2 101
#: samples long at -110 dB, 8 542 at -130 dB; the sum stays within -110 dB of the
#: FFT sum there)
TAIL_ENERGY = 1e-11
#: CPU seconds per multiply-add of the time-domain sum and per ``n log2 n`` of a
#: real FFT of length n (float32) with its share of the impulses and the products,
#: fitted to renders of 2-96 paths at 30 microphones, 8 000 and 22 000 samples,
#: with and without path responses (docs/physics.md, "Where a measurement's time
#: goes"): only their ratio matters.  Fitted with the sum of before its per-sample
#: registers (:mod:`._timedomain_kernel`: 1.9x faster on the shoebox since), so
#: the choice now leans to the FFTs near the crossing; kept so that no scene changed
#: domain (and bytes) with the faster sum
SECONDS_PER_TAP = 1.2e-10
SECONDS_PER_FFT_OP = 3e-10
#: threads that sum the microphones' blocks (the compiled sum releases the GIL), as
#: the frequency domain's FFTs run on two; only for sums of at least THREADED_TAPS
#: multiply-adds (the threads' hand-over costs tens of microseconds)
WORKERS = 2
THREADED_TAPS = 2_000_000


def filtered_calls(spectra: np.ndarray, n: int) -> tuple[np.ndarray, int]:
    """The sets' filtered calls in time: ``(calls (Q, L), lead)``.

    `spectra` (Q, n // 2 + 1) complex: each set's filter times the call's spectrum
    on an n-point real FFT, the call's first sample at time 0; the inverse transform
    is circular, so the response's part before time 0 sits at the end.  The calls
    are cut at both ends (:func:`trimmed`) to a stretch starting `lead` samples
    before the call's first sample (at most n samples).
    """
    x = sfft.irfft(spectra, n, axis=-1)
    # :func:`trimmed` of x rolled by n // 2 (the tails on both sides), without the
    # rolled copy: the energies rolled, the kept columns gathered
    shift = n // 2
    cut = _cut(np.roll(np.sum(x * x, axis=0), shift))
    if cut is None:
        return np.zeros((x.shape[0], 1)), 0
    lo, hi = cut
    return x[:, (np.arange(lo, hi) - shift) % n], shift - lo


def trimmed(x: np.ndarray, zero: int) -> tuple[np.ndarray, int]:
    """Calls `x` (Q, L0) whose first sample is at index `zero`, cut at each end
    where their summed energy beyond the cut falls below half of
    :data:`TAIL_ENERGY` of the total: ``(calls (Q, L), lead)``, the first sample
    now at index `lead`."""
    cut = _cut(np.sum(x * x, axis=0))
    if cut is None:
        return np.zeros((x.shape[0], 1)), 0
    lo, hi = cut
    return np.ascontiguousarray(x[:, lo:hi]), zero - lo


def _cut(energy: np.ndarray) -> tuple[int, int] | None:
    """The columns [lo, hi) of :func:`trimmed`'s cut of calls whose summed energy
    per sample is `energy` (L0,); None: no energy."""
    cum = np.cumsum(energy)
    total = cum[-1]
    if total <= 0:
        return None
    cut = 0.5 * TAIL_ENERGY * total
    lo = int(np.searchsorted(cum, cut, side="right"))
    hi = int(np.searchsorted(cum, total - cut, side="left")) + 1
    return lo, hi


def render_time(
    d: np.ndarray,
    gain: np.ndarray,
    calls: np.ndarray,
    *,
    lead: int,
    kernel: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    n_samples: int,
    row: np.ndarray | None = None,
    into: tuple[np.ndarray, int] | None = None,
) -> np.ndarray:
    """Microphone signals (M, n_samples): at every microphone m and path n, the
    path's filtered call ``calls[row[n]]`` (C, L; sample `lead` is the call's first)
    delayed by ``d[m, n]`` samples (M, N; from the output's sample 0) and scaled by
    ``gain[m, n]`` (M, N); or, `gain` (M, N, R), R gain sets (a moving pose's), the
    copy's call ``sum_r gain[m, n, r] calls[row[n] + r]``.

    `kernel`: ``(n0, phase, table, offsets)`` of :func:`acousim.synth.render._taps`:
    each delay's integer part n0 (M, N), its row of the tabulated weights `table`
    (P, K) and the taps' offsets (K,) from n0: the frequency-domain render's own
    fractional delays.  `row` (N,): each path's call (None: path n has row n).
    Samples beyond the output are dropped.  Each copy is summed over its taps in
    single precision (the calls stored so), the copies added in double.

    `into`: ``(out, lo)``, the sum added into `out` (M, T) instead of a new array
    (its sample i at ``out[:, lo + i]``, those outside ``[max(lo, 0), lo +
    n_samples)`` and `out` dropped): into zeros, the bits of copying the returned
    samples there, without the copy; returns `out`.
    """
    n0, phase, table, offsets = kernel
    M, N = d.shape
    if into is None:
        out, lo = np.zeros((M, n_samples)), 0
    else:
        out, lo = into
    # the output's columns of the sum's samples 0 .. n_samples - 1
    window = (max(lo, 0), max(min(lo + n_samples, out.shape[1]), 0))
    if N == 0:
        return out
    row = np.arange(N, dtype=np.intp) if row is None else np.asarray(row, np.intp)
    first = n0.astype(np.int64) + (int(offsets[0]) - lead + lo)
    calls = np.ascontiguousarray(calls, dtype=np.float32)
    gain = np.ascontiguousarray(gain if gain.ndim == 3 else gain[..., None], dtype=np.float64)
    phase = np.ascontiguousarray(phase, np.intp)
    module = optional_kernel("acousim.synth._timedomain_kernel")
    if module is None:
        _add_numpy(first, phase, gain, table, calls, row, out, window)
        return out
    _sum_compiled(module, (first, phase, gain), table, calls, row, out, window)
    return out


def _sum_compiled(module, copies, table, calls, row, out, window) -> None:
    """:func:`render_time`'s sum by the compiled kernel, the microphones in blocks
    on :data:`WORKERS` threads for large sums; `copies`: (first, phase, gain)."""
    compiled = module.add_delayed
    first, phase, gain = copies
    M, N = first.shape
    work = M * N * (table.shape[1] + gain.shape[2] - 1) * calls.shape[1]
    pad = module.pad_for(table.shape[1])
    padded = np.zeros((calls.shape[0], calls.shape[1] + 2 * pad), np.float32)
    padded[:, pad:-pad] = calls  # the compiled sum's zeros around each
    calls = padded
    args = (first, phase, gain)
    lo, hi = window
    n_blocks = WORKERS if work >= THREADED_TAPS else 1
    edges = np.linspace(0, M, min(n_blocks, M) + 1).astype(int)
    if edges.size <= 2:
        compiled(*args, table, calls, row, out, lo, hi)
        return
    # each block of microphones its own rows of `out`: the same bits as one block;
    # the last block summed in this thread
    blocks = list(zip(edges[:-1], edges[1:]))
    done = [
        _pool().submit(compiled, *(a[i:j] for a in args), table, calls, row, out[i:j], lo, hi)
        for i, j in blocks[:-1]
    ]
    i, j = blocks[-1]
    compiled(*(a[i:j] for a in args), table, calls, row, out[i:j], lo, hi)
    for job in done:
        job.result()


def _pool() -> ThreadPoolExecutor:
    """The threads of the blocked sums (started on first use, shared), this
    process's: a forked child has none of its parent's threads, so it gets its own."""
    return _pool_of(os.getpid())


@cache
def _pool_of(pid: int) -> ThreadPoolExecutor:
    return ThreadPoolExecutor(WORKERS, thread_name_prefix="acousim-timedomain")


def _add_numpy(first, phase, gain, table, calls, row, out, window) -> None:
    """:func:`acousim.synth._timedomain_kernel.add_delayed` in numpy: per path and
    microphone, the copy's call (its gains times its rows of `calls`) convolved with
    its tap weights in single precision and added at its first tap, in the output's
    columns ``window`` = (lo, hi) only."""
    M, N, R = gain.shape
    K, L = table.shape[1], calls.shape[1]
    lo, T = window
    for n in range(N):
        rows = calls[row[n] : row[n] + R]  # (R, L)
        for m in range(M):
            mix = gain[m, n].astype(np.float32) @ rows  # (L,)
            y = np.convolve(mix, table[phase[m, n]].astype(np.float32))  # (L + K - 1,)
            s = int(first[m, n])
            i0, i1 = max(0, lo - s), min(L + K - 1, T - s)
            if i1 > i0:
                out[m, s + i0 : s + i1] += y[i0:i1]


def prefer_time(
    *, mics: int, paths: int, taps: int, call: int, sets: int, n_fft: int, mixed: int = 1
) -> bool:
    """Whether the time-domain sum is estimated to cost less than the frequency
    domain's: ``M N K L`` multiply-adds (K = 2 `taps` fractional-delay weights, L
    the filtered `call`'s samples) against ``M (Q + 1)`` real FFTs of `n_fft` points
    (Q `sets`: the forward ones, one inverse); each copy's call `mixed` from that many
    calls (a moving pose's gain sets: ``mixed - 1`` more multiply-adds a sample).
    Never without the compiled sum (numba missing): its numpy twin loops over the
    paths in Python, three times the FFTs' time on the shoebox."""
    if optional_kernel("acousim.synth._timedomain_kernel") is None:
        return False
    t_time = SECONDS_PER_TAP * mics * paths * (max(2 * taps, 1) + mixed - 1) * call
    t_freq = SECONDS_PER_FFT_OP * mics * (sets + 1) * n_fft * np.log2(max(n_fft, 2))
    return bool(t_time < t_freq)
