"""Recordings of different lengths (a real sensor's frame, a simulation's) are
compared over their common span: an echo at a known delay, synthesised here by a
frequency-domain delay of the sampled call (independent of the simulator), is found
in both at its range, and the report names the span."""

import json

import numpy as np
import pytest

import processing as P
from acousim.cli import main
from acousim.compare.comparable import common_span
from acousim.compare.comparison import ComparisonError, check_comparable, compare

FS = 450e3
C = 343.0
RANGE_M = 1.5
AZIMUTH_DEG = 20.0


def echo_recording(n_samples: int, seed: int) -> P.Recording:
    """A point reflector RANGE_M ahead at AZIMUTH_DEG (emitter at the array centre):
    each microphone hears the call delayed by (R + |s - p_m|) / c, plus white noise
    60 dB below the echo's peak."""
    array, call = P.urtis_v1(), P.rtis_call()
    az = np.deg2rad(AZIMUTH_DEG)
    source = RANGE_M * np.array([np.cos(az), np.sin(az), 0.0])
    delays = (RANGE_M + np.linalg.norm(source - array.positions_m, axis=1)) / C  # (M,)
    pulse = np.zeros(n_samples)
    x = call.sampled(FS)
    pulse[: len(x)] = x
    f = np.fft.rfftfreq(n_samples, 1 / FS)
    spectrum = np.fft.rfft(pulse)[None, :] * np.exp(-2j * np.pi * f[None, :] * delays[:, None])
    samples = np.fft.irfft(spectrum, n_samples)
    noise = np.random.default_rng(seed).normal(0, 1e-3 * np.max(np.abs(x)), samples.shape)
    return P.Recording(samples + noise, FS, array, call, speed_of_sound_m_s=C)


def test_different_lengths_are_compared_over_the_shorter():
    real, sim = echo_recording(6000, seed=1), echo_recording(6500, seed=2)
    check_comparable(real, sim)  # lengths alone are no reason to refuse
    report, _ = compare(real, sim, ("das",))
    span_m = 5999 / FS * C / 2  # the last common sample's range, emission at sample 0
    assert report.span.samples == 6000
    assert (report.span.real_samples, report.span.sim_samples) == (6000, 6500)
    assert report.span.range_m == pytest.approx(span_m)
    echo = max(report.images["das"].matched, key=lambda p: p.real.level_db)
    for peak in (echo.real, echo.sim):
        assert peak.range_m == pytest.approx(RANGE_M, abs=0.05)
        assert peak.azimuth_deg == pytest.approx(AZIMUTH_DEG, abs=2.0)


def test_the_command_names_the_common_span(tmp_path, capsys):
    P.save_recording(tmp_path / "real.h5", echo_recording(6000, seed=1))
    P.save_recording(tmp_path / "sim.h5", echo_recording(6500, seed=2))
    argv = ["compare", str(tmp_path / "real.h5"), "--sim", str(tmp_path / "sim.h5")]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert f"compared over the first 6000 samples ({5999 / FS * C / 2:.2f} m)" in out
    assert "6500" in out
    span = json.loads((tmp_path / "o" / "comparison.json").read_text())["span"]
    assert (span["samples"], span["real_samples"], span["sim_samples"]) == (6000, 6000, 6500)


def test_real_mismatches_are_still_refused():
    a = echo_recording(2000, seed=1)
    b = P.Recording(a.samples, 500e3, a.array, a.waveform)
    with pytest.raises(ComparisonError, match="sample rates"):
        check_comparable(a, b)
    late = P.Recording(np.zeros((30, 3000)), FS, a.array, a.waveform, emission_index=2500)
    with pytest.raises(ComparisonError, match="emissions") as checked:
        check_comparable(a, late)
    with pytest.raises(ComparisonError) as cut:  # the same refusal, however reached
        common_span(a, late)
    assert str(cut.value) == str(checked.value)
    assert "sim at sample 2500, after the common span's 2000 samples" in str(cut.value)
