"""Simulated versus real: align two recordings of the same sensor and say how far
apart they are, at every stage of the pipeline.

1. Alignment: the time of emission from the direct emitter -> microphone path (the
   lag that best aligns the first milliseconds of the two matched-filter outputs,
   refined to a fraction of a sample), then one overall gain by least squares on
   the matched-filter envelopes after the direct path (the echoes).  Without a
   direct path in the simulation, the whole recording sets the lag.  Both are
   reported, never hidden.
2. Per channel: matched-filter envelopes (zero-padded Hilbert transform), their
   correlation and their level difference in dB along range.
3. Range profiles (mean envelope power over channels).
4. Images of the same methods; their peaks matched one to one
   (:func:`scipy.optimize.linear_sum_assignment`), with the range, azimuth,
   elevation and level differences of each matched echo.
5. Unmatched peaks within one STFT window in range of a stronger peak of the same
   image are that echo's side lobes (the window spreads one echo over the range
   bins it overlaps, and the array's beam pattern puts lobes beside it in angle):
   reported as side lobes with the array's own response there, not as echoes
   only one side has.  What is left is listed as only in the real image or only
   in the simulation.

The results are typed (:class:`Comparison`, :class:`TrajectorySummary`); their
``to_dict()`` is what ``comparison.json`` and ``summary.json`` hold.  Loading what
the command line is given (:func:`load_real_recordings`) and pairing each real
recording with its simulation (:func:`pair_with_scene`, :func:`pair_with_file`)
live here too.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy.fft import next_fast_len
from scipy.optimize import linear_sum_assignment
from scipy.signal import hilbert

import processing as P
from acousim.compare.account import floor_start, noise_floor
from acousim.compare.echoes import (
    MIN_ECHO_ABOVE_FLOOR_DB,
    above_floor,
    reject_reason,
    traced_kinds,
)
from processing.base.atomic import atomic_path, write_text
from processing.base.errors import InputError

__all__ = [
    "ComparisonError",
    "check_comparable",
    "align",
    "envelope",
    "compare",
    "write_comparison",
    "comparison_figure",
    "noise_floor",
    "Peak",
    "MatchedEcho",
    "RejectedPair",
    "MIN_ECHO_ABOVE_FLOOR_DB",
    "SideLobe",
    "MethodComparison",
    "Alignment",
    "Comparison",
    "ComparisonArrays",
]

DIRECT_WINDOW_S = 1.0e-3  # beyond the call: the direct path's part used for alignment


class ComparisonError(InputError):
    """The two recordings cannot be compared; the message names what differs."""


CALL_RTOL = 1e-3
"""Two calls are the same when of one kind with frequencies and durations within this
(relative) and tapers within 0.01: a call fitted to a CHIRP file's transmitter
samples (:func:`processing.sensor.calls.fit_sweep`) is the preset within 1e-6. Their
amplitudes are a gain, which the alignment estimates."""


def same_call(a: P.Waveform, b: P.Waveform) -> bool:
    """Whether two calls are the same within :data:`CALL_RTOL`."""
    pairs = [(a.f_start_hz, b.f_start_hz), (a.f_end_hz, b.f_end_hz), (a.duration_s, b.duration_s)]
    return (
        a.kind == b.kind
        and all(abs(x - y) <= CALL_RTOL * abs(y) for x, y in pairs)
        and abs(a.taper - b.taper) <= 0.01
    )


def check_comparable(real: P.Recording, sim: P.Recording) -> None:
    diffs = []
    if real.array.n_mics != sim.array.n_mics or not np.allclose(
        real.array.positions_m, sim.array.positions_m, atol=1e-6
    ):
        diffs.append(
            f"arrays ({real.array.name}, {real.array.n_mics} mics vs "
            f"{sim.array.name}, {sim.array.n_mics} mics)"
        )
    if real.sample_rate_hz != sim.sample_rate_hz:
        diffs.append(f"sample rates ({real.sample_rate_hz:g} vs {sim.sample_rate_hz:g} Hz)")
    if real.n_samples != sim.n_samples:
        diffs.append(f"lengths ({real.n_samples} vs {sim.n_samples} samples)")
    if not same_call(real.waveform, sim.waveform):
        diffs.append(f"calls ({real.waveform.to_dict()} vs {sim.waveform.to_dict()})")
    if diffs:
        raise ComparisonError("the recordings differ in " + "; ".join(diffs))


def _mf(rec: P.Recording) -> np.ndarray:
    x = rec.samples if rec.samples.ndim == 2 else rec.samples.mean(axis=0)
    return P.matched_filter(x, rec.waveform.sampled(rec.sample_rate_hz))


def envelope(x: np.ndarray) -> np.ndarray:
    """Envelope |analytic signal| of x (..., T), zero-padded to twice its length: the
    FFT-based Hilbert transform is circular, and without padding the strong direct
    path at the start wraps around into the last samples (the range profiles' last
    0.5 m climbed 30-50 dB)."""
    n = x.shape[-1]
    return np.abs(hilbert(x, N=next_fast_len(2 * n), axis=-1)[..., :n])


def _shift(x: np.ndarray, samples: float) -> np.ndarray:
    """Delay x (..., T) by a fractional number of samples (FFT phase shift)."""
    n = x.shape[-1]
    f = np.fft.rfftfreq(2 * n)
    X = np.fft.rfft(x, 2 * n, axis=-1) * np.exp(-2j * np.pi * f * samples)
    return np.fft.irfft(X, 2 * n, axis=-1)[..., :n]


def align(real: P.Recording, sim: P.Recording, max_lag_s: float = 0.5e-3) -> tuple[float, float]:
    """(shift in samples to apply to `sim`, gain real/sim)."""
    return _align(real, _mf(real), _mf(sim), max_lag_s)[:2]


def _align(real: P.Recording, mf_r: np.ndarray, mf_s: np.ndarray, max_lag_s: float = 0.5e-3):
    """Lag, gain and the two matched-filter envelopes (the simulated one shifted by the
    lag, before the gain), from matched-filter outputs computed once by the caller."""
    fs = real.sample_rate_hz
    win = int((real.waveform.duration_s + DIRECT_WINDOW_S) * fs)
    # the direct path sets the time of emission; a simulation without one (or with
    # almost none) is aligned on the whole recording instead
    early = np.sum(mf_s[:, :win] ** 2) >= 0.01 * np.sum(mf_s**2)
    span = win if early else mf_s.shape[-1]
    a, b = mf_r[:, :span], mf_s[:, :span]
    max_lag = int(max_lag_s * fs)
    n = 2 * span
    xc = np.fft.irfft(np.fft.rfft(a, n) * np.conj(np.fft.rfft(b, n)), n).sum(axis=0)
    lags = np.concatenate([np.arange(0, max_lag + 1), np.arange(-max_lag, 0)])
    vals = np.concatenate([xc[: max_lag + 1], xc[n - max_lag :]])
    k = int(np.argmax(vals))
    lag = float(lags[k])
    # parabolic refinement
    left = vals[k - 1]  # vals runs over lags 0..max, -max..-1: index -1 is lag -1
    right = vals[(k + 1) % len(vals)]
    den = left - 2 * vals[k] + right
    if den < 0:
        lag += 0.5 * (left - right) / den
    # the gain: least squares on the matched-filter envelopes after the direct path
    # (the echoes): envelopes do not depend on the carrier's phase, and the direct
    # path of a real sensor is often clipped and would set the gain alone.  The
    # matched filter commutes with the delay, so its output is shifted, not recomputed.
    env_s = envelope(_shift(mf_s, lag))
    env_r = envelope(mf_r)
    denom = float(np.sum(env_s[:, win:] ** 2))
    gain = float(np.sum(env_r[:, win:] * env_s[:, win:]) / denom) if denom > 0 else 0.0
    return lag, gain, env_r, env_s


@dataclass(frozen=True)
class MatchTolerance:
    range_m: float = 0.3
    angle_deg: float = 15.0


def match_peaks(
    a: np.ndarray, b: np.ndarray, tol: MatchTolerance = MatchTolerance()
) -> tuple[list[tuple[int, int]], list[int], list[int]]:
    """One-to-one matching of peak tables (range, az, el, level): pairs, only-a, only-b."""
    if len(a) == 0 or len(b) == 0:
        return [], list(range(len(a))), list(range(len(b)))
    cost = (
        np.abs(a[:, None, 0] - b[None, :, 0]) / tol.range_m
        + np.hypot(a[:, None, 1] - b[None, :, 1], a[:, None, 2] - b[None, :, 2]) / tol.angle_deg
    )
    ia, ib = linear_sum_assignment(cost)
    pairs = [(int(i), int(j)) for i, j in zip(ia, ib) if cost[i, j] <= 2.0]
    ma = {i for i, _ in pairs}
    mb = {j for _, j in pairs}
    return (
        pairs,
        [i for i in range(len(a)) if i not in ma],
        [j for j in range(len(b)) if j not in mb],
    )


@dataclass(frozen=True)
class Peak:
    """One image peak: range (m), azimuth and elevation (degrees), level (dB re the
    image's maximum)."""

    range_m: float
    azimuth_deg: float
    elevation_deg: float
    level_db: float


@dataclass(frozen=True)
class MatchedEcho:
    """A peak of the real image paired with one of the simulated image: an echo both
    have.  `real_above_floor_db`: how far the real range profile at the real peak's
    range stands above its noise floor (dB); `sim_truth_kind`: the traced path the
    simulated peak shows (its peak table's ``truth_kind``; "" when the simulation
    has no ground truth to check it against)."""

    real: Peak
    sim: Peak
    real_above_floor_db: float = float("nan")
    sim_truth_kind: str = ""

    @property
    def d_range_m(self) -> float:
        return self.sim.range_m - self.real.range_m

    @property
    def d_azimuth_deg(self) -> float:
        return self.sim.azimuth_deg - self.real.azimuth_deg

    @property
    def d_elevation_deg(self) -> float:
        return self.sim.elevation_deg - self.real.elevation_deg

    @property
    def d_level_db(self) -> float:
        return self.sim.level_db - self.real.level_db

    def to_dict(self) -> dict:
        return {
            "real": asdict(self.real),
            "sim": asdict(self.sim),
            "d_range_m": self.d_range_m,
            "d_azimuth_deg": self.d_azimuth_deg,
            "d_elevation_deg": self.d_elevation_deg,
            "d_level_db": self.d_level_db,
            "real_above_noise_floor_db": self.real_above_floor_db,
            "sim_truth_kind": self.sim_truth_kind,
        }


@dataclass(frozen=True)
class RejectedPair:
    """Two peaks close enough to pair that are not an echo both have: `reason`
    (:func:`acousim.compare.echoes.reject_reason`)."""

    pair: MatchedEcho
    reason: str

    def to_dict(self) -> dict:
        return {**self.pair.to_dict(), "reason": self.reason}


@dataclass(frozen=True)
class SideLobe:
    """An unmatched peak within one STFT window in range of a stronger peak `of` of the
    same image: that echo's side lobe.  `array_response_db` is the array's narrow-band
    beam pattern (delay-and-sum, at the image's steering frequency) aimed at `of`,
    evaluated at this peak's direction: how strong a pure side lobe would be there."""

    peak: Peak
    of: Peak
    array_response_db: float

    def to_dict(self) -> dict:
        return {
            **asdict(self.peak),
            "of": asdict(self.of),
            "array_response_db": self.array_response_db,
        }


@dataclass(frozen=True)
class MethodComparison:
    """The peaks of one method's two images: matched echoes, side lobes, the rest."""

    method: str
    matched: tuple[MatchedEcho, ...]
    only_real: tuple[Peak, ...]
    only_sim: tuple[Peak, ...]
    side_lobes_real: tuple[SideLobe, ...]
    side_lobes_sim: tuple[SideLobe, ...]
    range_bin_m: float
    rejected: tuple[RejectedPair, ...] = ()
    sim_has_truth: bool = True
    real_max_above_floor_db: float = float("nan")
    only_real_above_floor: int = 0

    def to_dict(self) -> dict:
        return {
            "matched": [m.to_dict() for m in self.matched],
            "rejected_pairs": [r.to_dict() for r in self.rejected],
            "sim_has_truth": self.sim_has_truth,
            "min_echo_above_noise_floor_db": MIN_ECHO_ABOVE_FLOOR_DB,
            "real_max_above_noise_floor_db": self.real_max_above_floor_db,
            "only_real_above_noise_floor": self.only_real_above_floor,
            "only_real": [asdict(p) for p in self.only_real],
            "only_sim": [asdict(p) for p in self.only_sim],
            "side_lobes_real": [s.to_dict() for s in self.side_lobes_real],
            "side_lobes_sim": [s.to_dict() for s in self.side_lobes_sim],
            "range_bin_m": self.range_bin_m,
        }


@dataclass(frozen=True)
class Alignment:
    """Shift applied to the simulation (samples, and seconds) and gain real/sim."""

    emission_shift_samples: float
    emission_shift_s: float
    gain: float


@dataclass(frozen=True)
class Comparison:
    """Everything :func:`compare` measured.  `level_difference_db` (B,) is
    10 log10(real / simulated) per `range_bin_m` range bin after alignment and gain."""

    alignment: Alignment
    envelope_correlation: tuple[float, ...]
    range_bin_m: float
    level_difference_db: tuple[float, ...]
    images: dict[str, MethodComparison]

    @property
    def mean_envelope_correlation(self) -> float:
        return float(np.mean(self.envelope_correlation))

    def to_dict(self) -> dict:
        return {
            "alignment": asdict(self.alignment),
            "channels": {
                "envelope_correlation": list(self.envelope_correlation),
                "mean_envelope_correlation": self.mean_envelope_correlation,
            },
            "range_profile": {
                "range_bin_m": self.range_bin_m,
                "level_difference_db": list(self.level_difference_db),
                "note": "10 log10(real / simulated) per range bin, after alignment and gain",
            },
            "images": {m: r.to_dict() for m, r in self.images.items()},
        }


@dataclass(frozen=True, eq=False)
class ComparisonArrays:
    """What the picture draws: range-bin edges (B + 1,) in m, the two range profiles
    (B,) (mean envelope power) and the images of each method."""

    edges_m: np.ndarray
    profile_real: np.ndarray
    profile_sim: np.ndarray
    images_real: dict[str, P.Image]
    images_sim: dict[str, P.Image]


def _peaks(img: P.Image, threshold_db: float) -> list[Peak]:
    pk = img.peaks(threshold_db)
    return [
        Peak(float(r), float(np.rad2deg(a)), float(np.rad2deg(e)), float(lv))
        for r, a, e, lv in zip(pk.range_m, pk.azimuth_rad, pk.elevation_rad, pk.level_db)
    ]


def _table(peaks: Sequence[Peak]) -> np.ndarray:
    return np.array(
        [[p.range_m, p.azimuth_deg, p.elevation_deg, p.level_db] for p in peaks]
    ).reshape(-1, 4)


def _unit(az_deg: float, el_deg: float) -> np.ndarray:
    az, el = np.deg2rad(az_deg), np.deg2rad(el_deg)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def array_response_db(
    array: P.Array, frequency_hz: float, c: float, towards: Peak, at: Peak
) -> float:
    """Narrow-band delay-and-sum beam pattern aimed at `towards`, at `at`'s direction,
    in dB re its maximum: |a(at)^H a(towards)|^2 / M^2."""
    k = 2 * np.pi * frequency_hz / c
    pos = array.positions_m
    a0 = np.exp(1j * k * pos @ _unit(towards.azimuth_deg, towards.elevation_deg))
    a1 = np.exp(1j * k * pos @ _unit(at.azimuth_deg, at.elevation_deg))
    r = abs(np.vdot(a1, a0)) ** 2 / len(pos) ** 2
    return float(10 * np.log10(max(r, 1e-30)))


def side_lobes(
    peaks: Sequence[Peak],
    candidates: Sequence[int],
    extent_m: float,
    array: P.Array,
    frequency_hz: float,
    c: float,
) -> tuple[list[SideLobe], list[int]]:
    """Split `candidates` (indices into `peaks`, strongest first) into side lobes of a
    stronger peak within `extent_m` in range, and the rest."""
    lobes, rest = [], []
    for i in candidates:
        p = peaks[i]
        parents = [
            q for q in peaks if q.level_db > p.level_db and abs(q.range_m - p.range_m) <= extent_m
        ]
        if parents:
            top = max(parents, key=lambda q: q.level_db)
            lobes.append(SideLobe(p, top, array_response_db(array, frequency_hz, c, top, p)))
        else:
            rest.append(i)
    return lobes, rest


def _range_profiles(rng, env_r, env_s, range_bin_m: float):
    """Energy of the envelopes (M, T) per range bin of `range_bin_m` over the ranges
    `rng` (T,): the bin edges, both profiles and their ratio in dB."""
    edges = np.arange(0, rng[-1] + range_bin_m, range_bin_m)
    idx = np.clip(np.digitize(rng, edges) - 1, 0, len(edges) - 2)
    prof_r = np.bincount(idx, (env_r**2).mean(axis=0), len(edges) - 1)
    prof_s = np.bincount(idx, (env_s**2).mean(axis=0), len(edges) - 1)
    tiny = 1e-30
    return edges, prof_r, prof_s, 10 * np.log10((prof_r + tiny) / (prof_s + tiny))


def _method(
    m: str, real: tuple, sim: tuple, above, *, threshold_db: float, extent_m: float, window: int
) -> MethodComparison:
    """The peaks of method `m`'s images compared: `real`, `sim` (recording, image)
    (the simulation aligned), `above(range_m)`: the real profile's margin over its
    noise floor there (dB)."""
    (rec_r, img_r), (rec_s, img_s) = real, sim
    c = rec_r.speed_of_sound_m_s
    a, b = _peaks(img_r, threshold_db), _peaks(img_s, threshold_db)
    pairs, only_r, only_s = match_peaks(_table(a), _table(b))
    f = img_r.frequency_hz
    lobes_r, only_r = side_lobes(a, only_r, extent_m, rec_r.array, f, c)
    lobes_s, only_s = side_lobes(b, only_s, extent_m, rec_s.array, f, c)
    kinds = traced_kinds(rec_s, img_s, threshold_db, window)
    has_truth = rec_s.truth is not None
    found = [MatchedEcho(a[i], b[j], above(a[i].range_m), kinds[j]) for i, j in pairs]
    why = [reject_reason(e.real_above_floor_db, e.sim_truth_kind, has_truth) for e in found]
    return MethodComparison(
        method=m,
        matched=tuple(e for e, r in zip(found, why) if not r),
        rejected=tuple(RejectedPair(e, r) for e, r in zip(found, why) if r),
        sim_has_truth=has_truth,
        real_max_above_floor_db=max((above(p.range_m) for p in a), default=float("nan")),
        only_real_above_floor=sum(above(a[i].range_m) >= MIN_ECHO_ABOVE_FLOOR_DB for i in only_r),
        only_real=tuple(a[i] for i in only_r),
        only_sim=tuple(b[j] for j in only_s),
        side_lobes_real=tuple(lobes_r),
        side_lobes_sim=tuple(lobes_s),
        range_bin_m=img_r.bin_range_m,
    )


def compare(
    real: P.Recording,
    sim: P.Recording,
    methods=("das",),
    settings: P.ProcessingSettings | None = None,
    threshold_db: float = -12.0,
    range_bin_m: float = 0.05,
) -> tuple[Comparison, ComparisonArrays]:
    """Compare two recordings (the steps of the module docstring).  Returns what was
    measured and what the picture draws."""
    check_comparable(real, sim)
    for rec in (real, sim):  # before the matched filters: an InputError, not a MemoryError
        P.check_memory(rec, methods, settings)
    lag, gain, env_r, env_s = _align(real, _mf(real), _mf(sim))
    env_s = gain * env_s
    fs, c = real.sample_rate_hz, real.speed_of_sound_m_s
    aligned = sim.with_samples(
        gain * _shift(sim.samples if sim.samples.ndim == 2 else sim.samples.mean(0), lag)
    )
    corr = tuple(
        float(np.corrcoef(er, es)[0, 1]) if er.std() > 0 and es.std() > 0 else 0.0
        for er, es in zip(env_r, env_s)
    )
    rng = real.time_s() * c / 2
    edges, prof_r, prof_s, level_db = _range_profiles(rng, env_r, env_s, range_bin_m)
    settings = settings or P.ProcessingSettings(
        energy_fraction=0.3,
        range_limits_m=(0.3, float(rng[-1])),
        grid=P.Grid.degrees((-90, 90), (-60, 60), 2),
    )
    # one echo spreads over the range bins of every STFT window that overlaps it
    extent_m = settings.window / fs * c / 2
    images_r = P.acoustic_images(real, methods, settings)
    images_s = P.acoustic_images(aligned, methods, settings)
    above = above_floor(edges, prof_r, extent_m)
    per_method = {
        m: _method(
            m,
            (real, images_r[m]),
            (aligned, images_s[m]),
            above,
            threshold_db=threshold_db,
            extent_m=extent_m,
            window=settings.window,
        )
        for m in methods
    }
    report = Comparison(
        alignment=Alignment(lag, lag / fs, gain),
        envelope_correlation=corr,
        range_bin_m=range_bin_m,
        level_difference_db=tuple(level_db.tolist()),
        images=per_method,
    )
    return report, ComparisonArrays(edges, prof_r, prof_s, images_r, images_s)


def write_comparison(
    report: Comparison, arrays: ComparisonArrays, out_dir: str | Path
) -> list[Path]:
    """The JSON report and a side-by-side picture (:func:`comparison_figure`), written
    atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    js = write_text(out / "comparison.json", json.dumps(report.to_dict(), indent=1))
    fig = comparison_figure(report, arrays)
    png = out / "comparison.png"
    with atomic_path(png) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
    return [js, png]


#: the dynamic range of the comparison's fans (dB)
COMPARISON_RANGE_DB = 30.0


def comparison_figure(report: Comparison, arrays: ComparisonArrays):
    """Per method, the real and the simulated fan on one scale (dB re the strongest
    cell of the two, each with its colour bar; the matched echoes numbered) and the
    two range profiles in dB re the real profile's strongest bin, with each profile's
    noise floor (:func:`acousim.compare.account.noise_floor`, the number the command
    prints) drawn and named.  Returns the matplotlib Figure."""
    import matplotlib.pyplot as plt

    from acousim.viz.fan import colorbar_label, common_extent, draw_fan

    methods = list(arrays.images_real)
    fig, axes = plt.subplots(
        len(methods), 3, figsize=(16, 4.6 * len(methods)), squeeze=False, layout="constrained"
    )
    for row, m in zip(axes, methods):
        pair = (arrays.images_real[m], arrays.images_sim[m])
        top = 1.05 * max([float(im.range_m.max()) for im in pair if im.range_m.size] or [1.0])
        extent = common_extent(pair, top, COMPARISON_RANGE_DB)
        ref = max([float(im.power.max()) for im in pair if im.power.size] or [1.0])
        for ax, img, name in ((row[0], pair[0], "real"), (row[1], pair[1], "simulated")):
            im = draw_fan(ax, img, top, COMPARISON_RANGE_DB, extent=extent, reference=ref)
            fig.colorbar(im, ax=ax, shrink=0.85, label=colorbar_label(COMPARISON_RANGE_DB, True))
            ax.set_title(f"{name}, {m}")
        for k, echo in enumerate(report.images[m].matched):
            for ax, p in ((row[0], echo.real), (row[1], echo.sim)):
                a = np.deg2rad(p.azimuth_deg)
                xy = (p.range_m * np.sin(a), p.range_m * np.cos(a))
                ax.plot(*xy, "o", mfc="none", mec="cyan", ms=10)
                ax.annotate(str(k), xy, color="cyan", fontsize=8)
        _profiles(row[2], report, arrays)
    fig.suptitle(
        "real and simulated (aligned, gain fitted): fans on one scale, cyan circles: "
        "matched echoes",
        fontsize=10,
    )
    return fig


def _profiles(ax, report: Comparison, arrays: ComparisonArrays) -> None:
    """The two range profiles in dB re the real one's strongest bin, and their floors."""
    centres = (arrays.edges_m[1:] + arrays.edges_m[:-1]) / 2
    ref = float(arrays.profile_real.max()) if arrays.profile_real.size else 0.0
    ref = ref if ref > 0 else 1.0

    def db(x):
        return 10 * np.log10(np.maximum(np.asarray(x, float) / ref, 1e-30))

    for prof, name, colour in (
        (arrays.profile_real, "real", "C0"),
        (arrays.profile_sim, "simulated (aligned)", "C1"),
    ):
        floor = float(db(noise_floor(prof)))  # the account's, as the command prints it
        ax.plot(centres, db(prof), color=colour, lw=1, label=name)
        ax.axhline(floor, color=colour, ls="--", lw=1, label=f"{name} noise floor: {floor:.1f} dB")
    ax.set_xlabel("range (m)")
    ax.set_ylabel("mean envelope power (dB re real strongest bin)")
    ax.legend(fontsize=8)
    al = report.alignment
    ax.set_title(
        f"range profiles ({report.range_bin_m * 100:g} cm bins); gain {al.gain:.3g}, "
        f"shift {al.emission_shift_samples:.2f} samples\nnoise floor: each profile's median "
        f"over {arrays.edges_m[floor_start(len(centres))]:.2f}-{arrays.edges_m[-1]:.2f} m",
        fontsize=9,
    )
