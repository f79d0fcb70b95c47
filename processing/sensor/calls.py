"""Emitted calls: the paper's linear chirp and the RTIS hyperbolic sweep.

A :class:`Waveform` is defined analytically, so it can be evaluated at any time
(:meth:`Waveform.at`, used by the simulator for exact fractional delays) and sampled
at any rate (:meth:`Waveform.sampled`).  Time 0 is the first sample of the emission.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from processing.base.errors import InputError, unknown_choice

#: Anti-alias cut-off of recorded calls, as a fraction of the Nyquist frequency.
ANTI_ALIAS_CUTOFF = 0.8

__all__ = [
    "Waveform",
    "linear_chirp",
    "hyperbolic_sweep",
    "paper_chirp",
    "rtis_call",
    "CALLS",
    "named_call",
    "MAX_FREQUENCY_HZ",
    "sweep_phase",
    "MAX_DURATION_S",
    "fit_sweep",
    "FIT_MIN_CORRELATION",
]

MAX_FREQUENCY_HZ = 1e9
"""Highest frequency (Hz) of a call: far above any air-borne ultrasound."""
MAX_DURATION_S = 1e3
"""Longest call (s); the memory estimate refuses far shorter ones at a high rate."""

#: :func:`fit_sweep` accepts a fit whose analytic signal correlates at least this well
#: with the sampled call (magnitude of the normalised complex correlation)
FIT_MIN_CORRELATION = 0.95


@dataclass(frozen=True)
class Waveform:
    """An analytic frequency sweep.

    Attributes
    ----------
    kind : {'linear', 'hyperbolic'}
        Linear: frequency linear in time.  Hyperbolic: period linear in time (the
        RTIS calls).
    f_start_hz, f_end_hz : float
        Instantaneous frequency at t = 0 and t = duration.
    duration_s : float
        Length of the call.
    taper : float
        Fraction of the duration shaped by a half-Hann ramp at each end (0: none).
    amplitude : float
        Peak amplitude.
    """

    kind: str
    f_start_hz: float
    f_end_hz: float
    duration_s: float
    taper: float = 0.0
    amplitude: float = 1.0

    def __post_init__(self) -> None:
        if self.kind not in ("linear", "hyperbolic"):
            raise InputError(
                "must be 'linear' or 'hyperbolic'", key="waveform.kind", value=self.kind
            )
        for name, lo, hi in (
            ("f_start_hz", 0.0, MAX_FREQUENCY_HZ),
            ("f_end_hz", 0.0, MAX_FREQUENCY_HZ),
            ("duration_s", 0.0, MAX_DURATION_S),
            ("taper", -1.0, 0.5),
            ("amplitude", -math.inf, math.inf),
        ):
            v = getattr(self, name)
            ok = isinstance(v, int | float | np.number) and not isinstance(v, bool)
            if not (ok and math.isfinite(v) and lo < v <= hi and (name != "taper" or v >= 0)):
                what = "in [0, 0.5]" if name == "taper" else f"in (0, {hi:g}]"
                if name == "amplitude":
                    what = "finite"
                raise InputError(f"must be a number {what}", key=f"waveform.{name}", value=v)
            object.__setattr__(self, name, float(v))

    @property
    def band_hz(self) -> tuple[float, float]:
        """(lowest, highest) instantaneous frequency."""
        return min(self.f_start_hz, self.f_end_hz), max(self.f_start_hz, self.f_end_hz)

    def at(self, t_s: np.ndarray) -> np.ndarray:
        """Evaluate the call at times `t_s` (seconds, any shape); zero outside [0, T)."""
        t = np.asarray(t_s, dtype=float)
        T = self.duration_s
        inside = (t >= 0) & (t < T)
        tc = np.where(inside, t, 0.0)
        # a sine from phase 0 (as cos(phase - 90 degrees), to the bit scipy's chirp)
        y = np.cos(sweep_phase(tc, self.f_start_hz, T, self.f_end_hz, self.kind) + _MINUS_90)
        if self.taper > 0:
            ramp = self.taper * T
            edge = np.minimum(tc, T - tc) / ramp
            y = y * np.where(edge < 1, 0.5 * (1 - np.cos(np.pi * np.clip(edge, 0, 1))), 1.0)
        return np.where(inside, self.amplitude * y, 0.0)

    def sampled(self, sample_rate_hz: float) -> np.ndarray:
        """The call sampled at `sample_rate_hz`: shape (ceil(T * fs),)."""
        if not sample_rate_hz > 0:
            raise ValueError(f"sample_rate_hz must be positive, got {sample_rate_hz}")
        n = int(np.ceil(self.duration_s * sample_rate_hz - 1e-9))
        return self.at(np.arange(n) / sample_rate_hz)

    def band_limited(
        self,
        sample_rate_hz: float,
        oversample: int = 64,
        pad: int = 256,
        cutoff: float = ANTI_ALIAS_CUTOFF,
    ) -> tuple[np.ndarray, int]:
        """The call as an anti-aliased sampling system records it.

        Evaluated at ``oversample`` times the rate, low-passed by an ideal filter at
        ``cutoff`` times the Nyquist frequency (the RTIS sensors cut at 100 kHz of
        225) and decimated.  Returns ``(samples, start)``: sample ``i`` is at
        time ``(i + start) / fs``; ``start = -pad`` keeps the filter's pre-ringing.
        An untapered call's edges alias otherwise: sampled directly it differs from
        this by about -42 dB (the paper's chirp at 500 kHz).
        """
        return _band_limited(self, float(sample_rate_hz), int(oversample), int(pad), float(cutoff))

    def to_dict(self) -> dict:
        """Plain-data form (for files)."""
        return {
            "kind": self.kind,
            "f_start_hz": self.f_start_hz,
            "f_end_hz": self.f_end_hz,
            "duration_s": self.duration_s,
            "taper": self.taper,
            "amplitude": self.amplitude,
        }

    @classmethod
    def from_dict(cls, d: dict) -> Waveform:
        """From :meth:`to_dict`'s form; an InputError naming a missing, unknown or
        malformed field."""
        if not isinstance(d, dict):
            raise InputError("must be an object {kind, f_start_hz, ...}", key="waveform", value=d)
        known = {"kind", "f_start_hz", "f_end_hz", "duration_s", "taper", "amplitude"}
        unknown = sorted(set(d) - known)
        if unknown:
            raise InputError("unknown field", key=f"waveform.{unknown[0]}", value=d[unknown[0]])
        missing = sorted({"kind", "f_start_hz", "f_end_hz", "duration_s"} - set(d))
        if missing:
            raise InputError("missing", key=f"waveform.{missing[0]}")
        return cls(**d)


_MINUS_90 = np.deg2rad(-90.0)


def sweep_phase(t: np.ndarray, f0: float, t1: float, f1: float, kind: str) -> np.ndarray:
    """The phase (rad) at times `t` (s) of a sweep from `f0` at t = 0 to `f1` at `t1`
    (Hz, s), zero at t = 0: ``kind`` "linear", frequency f0 + (f1 - f0) t / t1, phase
    2 pi (f0 t + (f1 - f0) t^2 / (2 t1)); otherwise hyperbolic, frequency
    f0 f1 t1 / (f0 t1 + (f1 - f0) t) (the period changes linearly), phase
    2 pi f0 s ln|1 - t / s| with the pole at s = f1 t1 / (f1 - f0) (t1 beyond its end).

    scipy.signal.chirp's linear and hyperbolic phases, written out here (its import
    takes about a second, and a simulation needs nothing else of scipy.signal): the
    same numbers to the bit, tested against it.
    """
    t = np.asarray(t, dtype=float)
    f0, t1, f1 = float(f0), float(t1), float(f1)
    if kind == "linear":
        rate = (f1 - f0) / t1
        return 2 * np.pi * (f0 * t + 0.5 * rate * t * t)
    if f0 == f1:
        return 2 * np.pi * f0 * t
    pole = -f1 * t1 / (f0 - f1)
    return 2 * np.pi * (-pole * f0) * np.log(np.abs(1 - t / pole))


def linear_chirp(
    f_start_hz: float = 20e3, f_end_hz: float = 85e3, duration_s: float = 1e-3, taper: float = 0.0
) -> Waveform:
    """A linear frequency sweep (sine phase: it starts at zero)."""
    return Waveform("linear", f_start_hz, f_end_hz, duration_s, taper)


def hyperbolic_sweep(
    f_max_hz: float = 50e3, f_min_hz: float = 25e3, duration_s: float = 2.5e-3, taper: float = 0.1
) -> Waveform:
    """The RTIS call: period grows linearly from 1/f_max to 1/f_min; Hann ramps."""
    return Waveform("hyperbolic", f_max_hz, f_min_hz, duration_s, taper)


def paper_chirp() -> Waveform:
    """The paper's simulated call: linear 20 -> 85 kHz, 1 ms, no taper."""
    return linear_chirp(20e3, 85e3, 1e-3)


def rtis_call(preset: str = "default_25_50") -> Waveform:
    """An RTIS call preset: ``default_25_50`` or ``default_20_80`` (2.5 ms)."""
    presets = {"default_25_50": (50e3, 25e3), "default_20_80": (80e3, 20e3)}
    if preset not in presets:
        raise InputError(
            unknown_choice("RTIS call preset", preset, presets),
            key="call",
            value=preset,
        )
    f_max, f_min = presets[preset]
    return hyperbolic_sweep(f_max, f_min, 2.5e-3, 0.1)


#: the calls a scene file (``[sensor] call = "..."``), ``acousim.Sensor(call="...")`` and
#: the command line's ``--call`` name: the RTIS presets and the paper's chirp
CALLS = ("default_25_50", "default_20_80", "paper")


def named_call(name: str) -> Waveform:
    """The call of a name of :data:`CALLS` (an InputError with a did-you-mean else)."""
    if name not in CALLS:
        raise InputError(unknown_choice("call", name, CALLS), key="call", value=name)
    return paper_chirp() if name == "paper" else rtis_call(name)


def fit_sweep(signal: np.ndarray, sample_rate_hz: float) -> tuple[Waveform, float, int]:
    """The :class:`Waveform` that best describes a sampled call, and how well.

    A file may hold the emitted call only as samples (a CHIRP transmitter's
    ``signals``). The instantaneous frequency (phase of the analytic signal) where the
    envelope is above half its peak (the middle 80 % of that time: the analytic
    signal rings at abrupt edges) is fitted by a line in time (``linear``) and by a
    line in period (``hyperbolic``), the better kept; its values at the call's ends
    give the frequencies. The call starts at its first non-zero sample or the one
    before (a call that starts in sine phase has a zero first sample), whichever
    correlates better; its taper is the one of 0, 0.05, ..., 0.5 that correlates
    best. Returns ``(waveform, correlation, start)``: the magnitude of the normalised
    complex correlation between the fit and the samples (1: the same call up to its
    phase; callers accept it above :data:`FIT_MIN_CORRELATION`), and the sample of
    `signal` at which the call starts (after leading zeros).
    """
    x = np.asarray(signal, float).reshape(-1)
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if x.size < 8 or not peak > 0 or not np.all(np.isfinite(x)):
        raise ValueError("a call needs at least 8 finite samples, not all zero")
    nz = np.flatnonzero(np.abs(x) > 1e-9 * peak)
    end = int(nz[-1]) + 1
    starts = sorted({max(int(nz[0]) - 1, 0), int(nz[0])})
    fits = [(*_fit_from(x[s:end], float(sample_rate_hz)), s) for s in starts]
    return max(fits, key=lambda r: r[1])


def _fit_from(x: np.ndarray, fs: float) -> tuple[Waveform, float]:
    """:func:`fit_sweep` for a call that starts at x[0] and ends at x[-1]."""
    from scipy.signal import hilbert

    z = hilbert(x)
    env = np.abs(z)
    f = np.diff(np.unwrap(np.angle(z))) * fs / (2 * np.pi)  # at (i + 0.5) / fs
    t = (np.arange(f.size) + 0.5) / fs
    strong = (env[:-1] > 0.5 * env.max()) & (env[1:] > 0.5 * env.max()) & (f > 0)
    idx = np.flatnonzero(strong)  # the middle 80 % of those
    strong[idx[: len(idx) // 10]] = strong[idx[len(idx) - len(idx) // 10 :]] = False
    if strong.sum() < 4:
        raise ValueError("the call is too short or too weak to fit")
    T = x.size / fs
    best: tuple | None = None
    for kind, g, inv in (("linear", f, lambda v: v), ("hyperbolic", 1 / f, lambda v: 1 / v)):
        coef = np.polyfit(t[strong], g[strong], 1)
        resid = np.std(inv(np.polyval(coef, t[strong])) - f[strong])
        if best is None or resid < best[0]:
            best = (resid, kind, inv(np.polyval(coef, 0.0)), inv(np.polyval(coef, T)))
    assert best is not None  # the loop ran twice
    _, kind, f0, f1 = best
    if not (f0 > 0 and f1 > 0 and np.isfinite(f0) and np.isfinite(f1)):
        raise ValueError("the call's frequency does not follow a sweep")
    fits = []
    for taper in np.round(np.linspace(0, 0.5, 11), 2):
        y = Waveform(kind, float(f0), float(f1), T, float(taper)).at(np.arange(x.size) / fs)
        h = hilbert(y)
        corr = abs(np.vdot(h, z)) / (np.linalg.norm(h) * np.linalg.norm(z))
        fits.append((corr, taper, float(np.max(np.abs(y)))))
    corr, taper, top = max(fits)
    amplitude = float(np.max(np.abs(x))) / top if top > 0 else 1.0
    return Waveform(kind, float(f0), float(f1), T, float(taper), amplitude), float(corr)


@lru_cache(maxsize=16)
def _band_limited(
    wf: Waveform, fs: float, oversample: int, pad: int, cutoff: float
) -> tuple[np.ndarray, int]:
    n = int(np.ceil(wf.duration_s * fs)) + 2 * pad
    t = (np.arange(n * oversample) - pad * oversample) / (oversample * fs)
    spec = np.fft.rfft(wf.at(t))
    spec[int(cutoff * n / 2) + 1 :] = 0.0  # keep |f| <= cutoff * fs / 2
    y = np.fft.irfft(spec, n * oversample)[::oversample]
    y.flags.writeable = False
    return y, -pad
