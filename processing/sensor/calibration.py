"""Array calibration: each microphone's gain and phase, and a common delay.

A real array's microphones differ by a few tenths of a dB and a few degrees, and the
recording's time origin may be off by a fraction of a millisecond.  Over the call's
band each microphone m is modelled as a constant gain g_m and a constant phase
phi_m (a Hilbert rotation: ``X_m'(f) = g_m e^{i phi_m} X_m(f)`` for f > 0), and every
echo arrives `delay_s` later than its geometry says:
``X_m'(f) = g_m e^{i phi_m} e^{-2 pi i f delay} X_m(f)``.

:func:`fit_array_calibration` fits them from one echo whose position is known (a
wall, a corner reflector; or :func:`processing.imaging.pipeline.find_echo`: the strongest
peak of the DAS image):
the echo is gated, each channel's spectrum multiplied by the call's conjugate and
undone by its geometric delay, and the resulting (channels x frequencies) matrix
taken as rank one, ``c_m h(f)`` (its leading singular pair): c the channels' complex
gains, h what they share (the call through the emitter, the air and the reflector:
a real sensor's response is not flat over the band), the common delay the one at
which h adds up most.  Only relative
gains and phases can be told from an echo of unknown strength: gains are given
relative to their mean (dB), phases relative to their circular mean.

:class:`ArrayCalibration` is what is stored: in a recording's metadata
(``metadata["array_calibration"]``: :meth:`ArrayCalibration.to_dict`, ``applied``
false or true), so that a recording file carries it; :func:`on_load` (called by
:func:`processing.load_recordings`) applies a calibration not yet applied.  Any other
file format stores the same dictionary (:meth:`~ArrayCalibration.to_dict`,
:meth:`~ArrayCalibration.from_dict`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft

from processing.base.errors import InputError
from processing.sensor.recording import Recording

__all__ = [
    "ArrayCalibration",
    "CalibrationFit",
    "METADATA_KEY",
    "apply_calibration",
    "attach_calibration",
    "on_load",
    "fit_array_calibration",
]

METADATA_KEY = "array_calibration"
GATE_MARGIN_S = 0.3e-3  # the echo's gate: its span over the array plus the call and this
MAX_DELAY_S = 0.2e-3  # largest common delay searched


@dataclass(frozen=True)
class ArrayCalibration:
    """Per-microphone gain (dB) and phase (rad) relative to the array's mean, and the
    common delay (s) by which echoes arrive later than their geometry says.
    `source` says what it was fitted from."""

    gain_db: tuple[float, ...]
    phase_rad: tuple[float, ...]
    delay_s: float = 0.0
    source: str = ""

    def __post_init__(self) -> None:
        g = tuple(float(v) for v in self.gain_db)
        p = tuple(float(v) for v in self.phase_rad)
        if len(g) != len(p) or not g:
            raise InputError(f"gain_db has {len(g)} values, phase has {len(p)}", key=METADATA_KEY)
        if not all(map(math.isfinite, (*g, *p, float(self.delay_s)))):
            raise InputError("must be finite numbers", key=METADATA_KEY, value=[g, p])
        object.__setattr__(self, "gain_db", g)
        object.__setattr__(self, "phase_rad", p)
        object.__setattr__(self, "delay_s", float(self.delay_s))

    @property
    def n_mics(self) -> int:
        return len(self.gain_db)

    def to_dict(self) -> dict:
        """JSON-ready: ``gain_db``, ``phase_deg`` (degrees in files), ``delay_s``,
        ``source``."""
        return {
            "gain_db": list(self.gain_db),
            "phase_deg": [math.degrees(v) for v in self.phase_rad],
            "delay_s": self.delay_s,
            "source": self.source,
        }

    @staticmethod
    def from_dict(d: dict, key: str = METADATA_KEY) -> ArrayCalibration:
        """The inverse of :meth:`to_dict`; InputError naming `key` if malformed."""
        try:
            return ArrayCalibration(
                tuple(d["gain_db"]),
                tuple(math.radians(float(v)) for v in d["phase_deg"]),
                float(d.get("delay_s", 0.0)),
                str(d.get("source", "")),
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"malformed array calibration ({exc})", key=key) from None

    def correct(self, samples: np.ndarray, sample_rate_hz: float) -> np.ndarray:
        """Samples (..., M, T) with the calibration removed: each channel divided by
        its gain, turned back by its phase, and all advanced by the delay (zero
        padded FFT: nothing wraps around)."""
        dtype = np.asarray(samples).dtype
        x = np.asarray(samples, float)
        if x.shape[-2] != self.n_mics:
            raise InputError(
                f"the calibration has {self.n_mics} microphones, the samples {x.shape[-2]}",
                key=METADATA_KEY,
            )
        T = x.shape[-1]
        n = sfft.next_fast_len(2 * T, real=True)
        f = np.arange(n // 2 + 1) * sample_rate_hz / n
        g = 10 ** (np.asarray(self.gain_db) / 20)
        h = np.exp(-1j * np.asarray(self.phase_rad))[:, None] / g[:, None]
        h = h * np.exp(2j * np.pi * f * self.delay_s)[None, :]
        h[:, 0] = 1 / g  # a phase is undefined at 0 Hz (and the call has no energy there)
        X = sfft.rfft(x, n, axis=-1) * h
        return sfft.irfft(X, n, axis=-1)[..., :T].astype(dtype)


def apply_calibration(recording: Recording, calibration: ArrayCalibration) -> Recording:
    """The recording corrected, its metadata holding the calibration as applied."""
    meta = dict(recording.metadata)
    meta[METADATA_KEY] = {**calibration.to_dict(), "applied": True}
    fixed = calibration.correct(recording.samples, recording.sample_rate_hz)
    return dataclasses.replace(recording, samples=fixed, metadata=meta)


def attach_calibration(recording: Recording, calibration: ArrayCalibration) -> Recording:
    """The recording as it is, carrying `calibration` to be applied when loaded."""
    meta = dict(recording.metadata)
    meta[METADATA_KEY] = {**calibration.to_dict(), "applied": False}
    return dataclasses.replace(recording, metadata=meta)


def on_load(recording: Recording, source=None) -> Recording:
    """A loaded recording with its stored calibration applied (if it has one that is
    not yet applied); a malformed one is an InputError naming `source` (the file)."""
    stored = recording.metadata.get(METADATA_KEY)
    if stored is None or (isinstance(stored, dict) and stored.get("applied") is True):
        return recording
    try:
        if not isinstance(stored, dict):
            raise InputError("must be a table", key=METADATA_KEY, value=stored)
        cal = ArrayCalibration.from_dict(stored)
        return apply_calibration(recording, cal)
    except InputError as exc:
        raise InputError(exc.reason, file=source, key=exc.key, value=exc.value) from None


@dataclass(frozen=True)
class CalibrationFit:
    """calibration; position_m (3,) of the echo used (sensor frame); residual_db
    (M,): each channel's misfit to the rank-one model over the band, relative to its
    echo (dB)."""

    calibration: ArrayCalibration
    position_m: np.ndarray
    residual_db: np.ndarray


def _geometry_delays(recording: Recording, position_m: np.ndarray, reflector: str) -> np.ndarray:
    """(M,) delays of the echo: via the point (``point``), or from the emitter's
    image in the plane through the point facing the array's centre (``plane``)."""
    arr, c = recording.array, recording.speed_of_sound_m_s
    p = np.asarray(position_m, float)
    if reflector == "point":
        return (np.linalg.norm(p - arr.emitter_m) + np.linalg.norm(p - arr.positions_m, axis=1)) / c
    if reflector != "plane":
        raise InputError("must be 'point' or 'plane'", key="reflector", value=reflector)
    u = (p - arr.positions_m.mean(axis=0)) / np.linalg.norm(p - arr.positions_m.mean(axis=0))
    image = arr.emitter_m + 2 * np.dot(p - arr.emitter_m, u) * u
    return np.linalg.norm(image - arr.positions_m, axis=1) / c


def _echo_matrix(recording: Recording, tau, gate_margin_s, band_hz, position_m):
    """The gated echo's spectra (M, K) times the call's conjugate with each channel's
    geometric delay `tau` (M,) undone, their FFT bins (K,) and the FFT length."""
    fs, e0 = recording.sample_rate_hz, recording.emission_index
    x = recording.samples if recording.samples.ndim == 2 else recording.samples.mean(axis=0)
    call = recording.waveform.sampled(fs)
    a = int(np.floor((tau.min() - gate_margin_s) * fs)) + e0
    b = int(np.ceil((tau.max() + gate_margin_s) * fs)) + e0 + call.size
    if a < 0 or b > x.shape[-1]:
        raise InputError(
            "the echo's gate lies outside the recording", key="position_m", value=list(position_m)
        )
    from scipy.signal import windows  # imported here: about a second, for a calibration alone

    seg = x[:, a:b] * windows.tukey(b - a, 0.2)
    n = sfft.next_fast_len(2 * (b - a), real=True)
    k = np.arange(n // 2 + 1)
    C = sfft.rfft(call, n)
    band = np.abs(C) > 0.5 * np.abs(C).max()
    if band_hz is not None:
        f = k * fs / n
        band &= (f >= min(band_hz)) & (f <= max(band_hz))
        if band.sum() < 8:
            raise InputError("holds too little of the call", key="band_hz", value=band_hz)
    k, C = k[band], C[band]
    X = sfft.rfft(seg, n, axis=-1)[:, band]
    D = (tau * fs + e0 - a)[:, None]  # each echo's delay in the segment (samples)
    return X * np.conj(C) * np.exp(2j * np.pi * k * D / n), k, n


def fit_array_calibration(
    recording: Recording,
    position_m,
    *,
    reflector: str = "point",
    gate_margin_s: float = GATE_MARGIN_S,
    band_hz: tuple[float, float] | None = None,
) -> CalibrationFit:
    """Fit an :class:`ArrayCalibration` from the echo of a reflector at `position_m`
    (sensor frame, m).  `reflector`: ``point`` (a corner reflector, a small
    object: the echo's path runs emitter -> point -> microphone) or ``plane`` (a
    wall or plate facing the array, `position_m` the foot of its normal through the
    array: the echo comes from the emitter's mirror image, whose wavefront is
    flatter; at 3.2 m across a 10 cm aperture the two differ by up to about 0.2 mm
    of path, 8 degrees at 40 kHz).  The echo is gated from its earliest arrival
    minus `gate_margin_s` to its latest plus the call and the margin; other echoes
    must lie outside.  The fit uses the frequencies where the call's spectrum is
    within 6 dB of its peak, inside `band_hz` (Hz) when given (two halves of the band
    fitted apart tell how far the model's constant phase holds)."""
    from scipy.optimize import minimize_scalar  # imported when used: processing stays light

    fs = recording.sample_rate_hz
    tau = _geometry_delays(recording, position_m, reflector)  # (M,)
    Z, k, n = _echo_matrix(recording, tau, gate_margin_s, band_hz, position_m)
    # Z ~ c_m h(f): the channels' complex gains times what they share (the call
    # through the emitter, the air and the reflector, and the common delay): the
    # leading singular pair (a real sensor's common response is not flat)
    U, sv, Vh = np.linalg.svd(Z, full_matrices=False)
    c, h = U[:, 0] * sv[0], Vh[0]
    model = np.outer(c, h)
    resid = np.sqrt(np.sum(np.abs(Z - model) ** 2, axis=1) / np.sum(np.abs(model) ** 2, axis=1))

    def power(d: float) -> float:  # the common delay: where h adds up most
        return -float(np.abs(np.sum(h * np.exp(2j * np.pi * k * d / n))))

    span = MAX_DELAY_S * fs
    grid = np.arange(-span, span + 0.25, 0.25)
    best = grid[int(np.argmin([power(d) for d in grid]))]
    d = minimize_scalar(power, bounds=(best - 0.5, best + 0.5), method="bounded").x
    gain = 20 * np.log10(np.abs(c))
    unit = c / np.abs(c)
    phase = np.angle(unit * np.conj(np.sum(unit)))
    cal = ArrayCalibration(
        tuple(gain - gain.mean()),
        tuple(phase - phase.mean()),
        d / fs,
        f"{reflector} echo at {np.round(np.asarray(position_m, float), 4).tolist()} m",
    )
    return CalibrationFit(cal, np.asarray(position_m, float), 20 * np.log10(resid))
