"""The FFT route of the renders: its FFT length for a moving pose
(:func:`acousim.synth.doppler._fft_length`: the span to the last echo's end and the
filters' tails) and its sum of the sets' products with their filters
(:mod:`acousim.synth._spectra_kernel` or numpy): the sum against a plain loop, and a
render whose echoes run past the recording's end against the same render on FFTs
four times as long (nothing can wrap there)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import processing as P
from acousim.core.echoes import Echoes
from acousim.synth import doppler
from acousim.synth.response import PathResponse
from processing.base.kernels import optional_kernel

render_mod = importlib.import_module("acousim.synth.render")

FS = 450e3


def _echoes_past_the_end(n_samples: int) -> tuple[Echoes, np.ndarray]:
    """Two microphones, 60 echoes whose last ones start 1 ms before the recording
    ends (the call lasts longer: their span is cut), Doppler factors within 0.4 %."""
    rng = np.random.default_rng(11)
    N = 60
    delay = np.sort(rng.uniform(1e-3, n_samples / FS - 1e-3, N))
    delay = delay[None] + rng.uniform(0, 2e-5, (2, N))
    length = 343.0 * delay
    gain = rng.uniform(0.2, 1.0, (2, N)) / length
    order = np.ones(N, int)
    angle = rng.uniform(0, 0.6, N)
    return Echoes(delay, gain, length, order, angle), 1 + rng.uniform(-4e-3, 4e-3, (2, N))


def test_trimmed_fft_wraps_nothing_into_the_recording(monkeypatch):
    n_samples = 4000
    echoes, rate = _echoes_past_the_end(n_samples)
    call = P.rtis_call("default_25_50")
    response = PathResponse(emitter_radius_m=0.004)
    reach_past = echoes.delay_s.max() * FS + call.duration_s * FS
    assert reach_past > n_samples + 100  # the echoes do run past the end

    def render():
        plan = doppler.plan_doppler(echoes, rate, call, FS, n_samples, response=response)
        return plan.n_fft, doppler.render_planned(plan)

    n, y = render()
    trimmed = doppler._fft_length
    monkeypatch.setattr(doppler, "_fft_length", lambda *a: 4 * trimmed(*a))
    n_long, y_long = render()
    assert n_long == 4 * n
    err = np.sum((y - y_long) ** 2) / np.sum(y_long**2)
    assert 10 * np.log10(err) < -100


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_summed_products_against_a_plain_loop(compiled, dtype, monkeypatch):
    if compiled and optional_kernel("acousim.synth._spectra_kernel") is None:
        pytest.skip("numba not installed")
    if not compiled:
        monkeypatch.setattr(render_mod, "optional_kernel", lambda *a: None)
    rng = np.random.default_rng(5)
    R, C, bins, b0, F = 3, 4, 50, 7, 30

    def cplx(*shape):
        return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(dtype)

    spectra, filt = cplx(R, C, bins), cplx(R, F)
    out = np.full((C + 1, bins), 9.0, dtype)  # the rows and bins outside kept
    render_mod._summed_products(spectra, filt, b0, out[:C], np.empty((C, F), dtype))
    ref = np.full((C + 1, bins), 9.0, complex)
    for c in range(C):
        for i in range(F):
            ref[c, b0 + i] = sum(
                complex(spectra[q, c, b0 + i]) * complex(filt[q, i]) for q in range(R)
            )
    tol = 1e-5 if dtype == np.complex64 else 1e-13
    assert np.max(np.abs(out - ref)) < tol * np.max(np.abs(ref))


@pytest.mark.parametrize("taper", [0.0, 0.1])
def test_one_echo_summed_in_time_as_by_fft(taper):
    """One echo of an untapered (its band-limit ringing spans the template) or a
    tapered call, with a path response: the sum in time (the filtered call from the
    plan's inverse FFT, :func:`acousim.synth.timedomain.filtered_calls`) and the sum
    by FFT on that length agree, and the echo's energy is the call's times its gain
    squared within the response's effect (the filtered call neither wrapped nor cut
    short on a span of one echo)."""
    import dataclasses

    from acousim.synth.options import DEFAULT_OPTIONS

    call = P.Waveform("linear", 30e3, 45e3, 2e-3, taper)
    delay = np.array([[3.1e-3, 3.1e-3 + 1e-6]]).T  # two microphones, one path
    echoes = Echoes(delay, np.full((2, 1), 0.5), 343.0 * delay, np.ones(1, int), np.zeros(1))
    rate = np.full((2, 1), 1.002)
    response = PathResponse(absorption=False, emitter_radius_m=0.004)
    y = {}
    for domain in ("time", "frequency"):
        opts = dataclasses.replace(DEFAULT_OPTIONS, domain=domain)
        plan = doppler.plan_doppler(echoes, rate, call, FS, 4000, options=opts, response=response)
        y[domain] = doppler.render_planned(plan)
    err = np.sum((y["time"] - y["frequency"]) ** 2) / np.sum(y["frequency"] ** 2)
    assert 10 * np.log10(err) < -60
    # the call's energy at 1.002 (time-scaled: over 1.002) times 0.25, the piston at
    # 0 rad is 1: the band-limited call's sum of squares, within 1 %
    ref = np.sum(call.band_limited(FS, oversample=64)[0] ** 2) / 1.002 * 0.25
    assert np.sum(y["frequency"][0] ** 2) == pytest.approx(ref, rel=0.01)
