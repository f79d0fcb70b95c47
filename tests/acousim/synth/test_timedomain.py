"""The full-rate render summed in time (``render_domain = "time"``,
acousim/synth/timedomain.py) against independent references: the echoes delayed
exactly in the frequency domain, each path filtered by its own response
(tests/acousim/synth/references.py, written apart from the renderers); and against
the render summed by FFTs, the same sum term for term (within -100 dB of its energy,
all microphones)."""

import dataclasses
import importlib
import tomllib
from pathlib import Path

import numpy as np
import pytest

import processing as P
from acousim.core.echoes import Echoes
from acousim.scene import load_scene, parse_scene
from acousim.simulator import Simulator
from acousim.synth import Capture, PathResponse, RenderOptions, render
from acousim.synth.doppler import render_doppler
from acousim.synth.render import render_with
from acousim.synth.timedomain import prefer_time
from processing.base.errors import InputError
from tests.acousim.synth.references import echoes_ahead, filtered_per_path
from tests.oracles.doppler import turning_past_four_points

FS = 450e3
SCENES = Path(__file__).resolve().parents[3] / "scenes"
FLAT = PathResponse(absorption=False)  # H = 1: exact delays only


def summed(e: Echoes, wf: P.Waveform, n: int, domain: str, **options) -> np.ndarray:
    """The render of `e` (M, N) at FS, `n` samples, summed in `domain`; `options`:
    the interpolator and the path response."""
    response = options.pop("response", None)
    capture = Capture(P.ura(1, e.delay_s.shape[0], 1e-3), wf, FS, n)
    return render_with(e, capture, RenderOptions(domain=domain, **options), response)


def residual_db(y: np.ndarray, ref: np.ndarray) -> float:
    """Energy of the difference over the reference's, all microphones, dB."""
    return float(10 * np.log10(np.sum((y - ref) ** 2) / np.sum(ref**2)))


@pytest.mark.parametrize("interpolator,bound_db", [("sinc", -80), ("lagrange", -80)])
def test_few_paths_summed_in_time_are_the_calls_delayed_exactly(interpolator, bound_db):
    """Flat responses: the exact sum of band-limited calls at fractional delays (the
    interpolators' own error sets the bound: -87 and -90 dB here, as the FFT sum),
    and the FFT sum within -100 dB."""
    arr = P.ura(2, 3, 3.85e-3)
    e = echoes_ahead(arr, n=7, seed=2)
    wf = P.rtis_call()
    exact = filtered_per_path(e, wf, FLAT, FS, 16384)
    y = summed(e, wf, 16384, "time", interpolator=interpolator)
    assert residual_db(y, exact) < bound_db
    fft = summed(e, wf, 16384, "frequency", interpolator=interpolator)
    assert residual_db(y, fft) < -100


def test_path_responses_summed_in_time_match_exact_per_path_filtering():
    """Absorption and a piston emitter: each path filtered by its own response
    (-75 dB: the factorisation's error, as for the FFT sum) and the FFT sum of the
    same factorised sets within -100 dB."""
    arr = P.ura(2, 2, 3.85e-3)
    e = echoes_ahead(arr, n=12, seed=6)
    wf = P.rtis_call()
    resp = PathResponse(emitter_radius_m=0.004)
    y = summed(e, wf, 16384, "time", response=resp)
    assert residual_db(y, filtered_per_path(e, wf, resp, FS, 16384)) < -75
    assert residual_db(y, summed(e, wf, 16384, "frequency", response=resp)) < -100


@pytest.mark.parametrize("interpolator", ["sinc", "lagrange", "nearest"])
def test_echoes_at_the_windows_edges_are_cut_as_the_fft_sum_cuts_them(interpolator):
    """A call starting before sample 0 (the direct path, 3 samples after the
    emission) and one running past the window's end: the same samples kept."""
    wf = P.rtis_call()
    delays = np.array([[3.0, 700.2, 7800.6], [3.4, 700.9, 7801.1]]) / FS
    e = Echoes(delays, np.ones((2, 3)), delays * 343.0, np.array([0, 1, 1]))
    for resp in (None, PathResponse()):
        kw = {"interpolator": interpolator, "response": resp}
        y = summed(e, wf, 8000, "time", **kw)
        ref = summed(e, wf, 8000, "frequency", **kw)
        assert np.any(y[:, -1])  # the last echo reaches the end
        assert residual_db(y, ref) < -100
    empty = Echoes.empty(2)
    assert not np.any(summed(empty, wf, 8000, "time"))


@pytest.mark.parametrize("name", ["shoebox", "wall", "points"])
def test_bundled_scenes_summed_in_time_are_their_fft_sums(name):
    """The shoebox (18 paths), the wall (one) and the points (three, no response):
    noise-free recordings within -100 dB of the FFT sum's, all microphones; 'auto'
    sums these few paths in time."""
    scene = load_scene(SCENES / f"{name}.toml")
    records = {}
    for domain in ("time", "frequency", "auto"):
        sim = dataclasses.replace(scene.simulation, render_domain=domain, snr_db=np.inf)
        sc = dataclasses.replace(scene, simulation=sim)
        records[domain] = Simulator(sc).simulate_pose(sc.sensor.poses[0]).samples
    assert np.any(records["time"])
    assert residual_db(records["time"], records["frequency"]) < -100
    assert records["auto"].tobytes() == records["time"].tobytes()


def test_a_moving_pose_summed_in_time_is_the_exact_doppler_echo():
    """Driving at 1 m/s and turning at 90 deg/s past four reflectors, with absorption
    and a piston emitter: the gain sets (Doppler terms times response terms) summed
    in time against each path's exact time-scaled echo, filtered by its own
    response (computed here; -60 dB, the Doppler renderer's bound), and against the
    same sets summed by FFT (-100 dB)."""
    case = turning_past_four_points(FS)
    y = {
        domain: render_doppler(
            case.echoes,
            case.rate,
            case.wf,
            FS,
            case.n,
            options=RenderOptions(domain=domain),
            response=case.response,
        )
        for domain in ("time", "frequency")
    }
    exact = case.exact
    assert residual_db(y["time"], exact) < -60
    assert residual_db(y["time"], y["frequency"]) < -100


def test_the_moving_shoebox_summed_in_time_is_its_fft_sum():
    """The bundled shoebox with the sensor driving at 1 m/s: the recordings within
    -100 dB; 'auto' sums its 18 paths in time."""
    data = tomllib.loads((SCENES / "shoebox.toml").read_text())
    data["sensor"]["pose"]["velocity_m_s"] = [1.0, 0.0, 0.0]
    scene = parse_scene(data, base_dir=SCENES)
    records = {}
    for domain in ("time", "frequency", "auto"):
        sc = dataclasses.replace(
            scene, simulation=dataclasses.replace(scene.simulation, render_domain=domain)
        )
        records[domain] = Simulator(sc).simulate_pose(sc.sensor.poses[0]).samples
    assert residual_db(records["time"], records["frequency"]) < -100
    assert records["auto"].tobytes() == records["time"].tobytes()


def test_the_numpy_sum_without_numba_gives_the_compiled_numbers(monkeypatch):
    pytest.importorskip("numba")
    td = importlib.import_module("acousim.synth.timedomain")
    arr = P.ura(2, 3, 3.85e-3)
    e = echoes_ahead(arr, n=9, seed=3, near_m=0.3)
    wf, resp = P.rtis_call(), PathResponse(emitter_radius_m=0.004)
    compiled = summed(e, wf, 16384, "time", response=resp)
    monkeypatch.setattr(td, "optional_kernel", lambda *a: None)
    plain = summed(e, wf, 16384, "time", response=resp)
    assert np.any(compiled)
    assert residual_db(plain, compiled) < -130  # single-precision sums in another order


def test_microphones_summed_in_threads_give_the_same_bits(monkeypatch):
    td = importlib.import_module("acousim.synth.timedomain")
    e = echoes_ahead(P.ura(3, 3, 3.85e-3), n=9, seed=8)
    wf, resp = P.rtis_call(), PathResponse()
    monkeypatch.setattr(td, "THREADED_TAPS", 0)  # every sum in blocks
    blocks = summed(e, wf, 16384, "time", response=resp)
    monkeypatch.setattr(td, "THREADED_TAPS", 10**18)  # none
    assert np.any(blocks)
    assert blocks.tobytes() == summed(e, wf, 16384, "time", response=resp).tobytes()


def _sum_in_child(e, reply) -> None:
    reply.put(summed(e, P.rtis_call(), 16384, "time", response=PathResponse()).tobytes())


def test_a_forked_child_sums_in_its_own_threads(monkeypatch):
    """The parent's threads are not in a forked child: it starts its own (a pool
    inherited without its threads would never run the blocks)."""
    import multiprocessing as mp

    if "fork" not in mp.get_all_start_methods():
        pytest.skip("no fork here")
    td = importlib.import_module("acousim.synth.timedomain")
    monkeypatch.setattr(td, "THREADED_TAPS", 0)
    e = echoes_ahead(P.ura(3, 3, 3.85e-3), n=9, seed=8)
    parent = summed(e, P.rtis_call(), 16384, "time", response=PathResponse())  # threads on
    ctx = mp.get_context("fork")
    reply = ctx.Queue()
    child = ctx.Process(target=_sum_in_child, args=(e, reply))
    child.start()
    try:
        assert reply.get(timeout=120) == parent.tobytes()
    finally:
        child.join(timeout=10)
        if child.is_alive():
            child.kill()


def test_render_sums_few_paths_in_time_and_thousands_by_fft():
    """`render` (no domain to give) takes the cheaper: the time domain's bytes for
    few paths."""
    e = echoes_ahead(P.ura(2, 3, 3.85e-3), n=5, seed=7)
    wf, resp = P.rtis_call(), PathResponse()
    assert render(e, wf, FS, 16384, response=resp).tobytes() == (
        summed(e, wf, 16384, "time", response=resp).tobytes()
    )
    fft = summed(e, wf, 16384, "frequency", response=resp)
    assert fft.tobytes() != summed(e, wf, 16384, "time", response=resp).tobytes()


def test_auto_sums_few_paths_in_time_and_thousands_by_fft():
    """The estimate's choice at the bundled scenes' sizes (30 microphones): the
    shoebox's 18 paths and 3 sets over a 12 000-point FFT in time; the corridor's
    4 000 paths by FFT."""
    shoebox = {"mics": 30, "taps": 6, "call": 2149, "sets": 3, "n_fft": 12000}
    assert prefer_time(paths=18, **shoebox)
    assert not prefer_time(paths=4000, **{**shoebox, "n_fft": 19200})


def test_auto_sums_by_fft_without_the_compiled_sum(monkeypatch):
    """Without numba the time-domain sum is its numpy twin, a loop over the paths:
    auto keeps the FFTs (the shoebox measured 22 ms in time against 8 by FFT)."""
    import acousim.synth.timedomain as td

    monkeypatch.setattr(td, "optional_kernel", lambda module, name=None: None)
    shoebox = {"mics": 30, "taps": 6, "call": 2149, "sets": 3, "n_fft": 12000}
    assert not prefer_time(paths=18, **shoebox)


def test_an_unknown_render_domain_is_an_input_error_naming_it():
    from acousim.scene.model import Simulation

    with pytest.raises(InputError, match="render_domain"):
        Simulation(render_domain="fourier")


@pytest.mark.parametrize("taps", [2, 5, 6, 8])
@pytest.mark.parametrize("sets", [1, 3])
def test_each_copy_is_its_call_convolved_with_its_weights(taps, sets):
    """The compiled sum (or its numpy twin) against each copy's mix of calls
    convolved with its tap weights in double precision and placed at its first tap
    (np.convolve, written here): within float32 rounding, for tap counts on and off
    a multiple of four, one call or three sets' mixed."""
    from acousim.synth.render import _taps
    from acousim.synth.timedomain import render_time

    rng = np.random.default_rng(taps * 10 + sets)
    M, N, L, T, lead = 3, 4, 300, 500, 7
    d = rng.uniform(-20.0, 480.0, (M, N))  # some copies cut at either end
    gain = rng.normal(size=(M, N, sets))
    calls = rng.normal(size=(N + sets - 1, L))
    row = np.arange(N)
    kernel = _taps(d, "lagrange", taps)
    y = render_time(d, gain, calls, lead=lead, kernel=kernel, n_samples=T, row=row)
    n0, phase, table, offsets = kernel
    want = np.zeros((M, T + 2 * L + 4 * taps))
    at = L + 2 * taps  # sample 0 of the output
    for m in range(M):
        for n in range(N):
            mix = gain[m, n] @ calls[row[n] : row[n] + sets]
            copy = np.convolve(mix, table[phase[m, n]])
            s = at + int(n0[m, n]) + int(offsets[0]) - lead
            want[m, s : s + copy.size] += copy
    want = want[:, at : at + T]
    assert np.any(want)
    assert residual_db(y, want) < -120


def test_a_sum_added_into_an_output_is_the_sum_placed_there():
    """``into=(out, lo)``: the same bits as the returned sum copied to columns lo..,
    the columns before 0 and from lo + n_samples on left as they were."""
    from acousim.synth.render import _taps
    from acousim.synth.timedomain import render_time

    rng = np.random.default_rng(4)
    d = rng.uniform(-30.0, 260.0, (2, 5))
    gain, calls = rng.normal(size=(2, 5)), rng.normal(size=(5, 120))
    args = dict(lead=40, kernel=_taps(d, "sinc", 6), n_samples=250)
    y = render_time(d, gain, calls, **args)
    for lo in (-60, 0, 75):
        out = np.zeros((2, 400))
        placed = out.copy()
        placed[:, max(lo, 0) : lo + 250] = y[:, max(lo, 0) - lo :]
        got = render_time(d, gain, calls, **args, into=(out, lo))
        assert got is out
        assert got.tobytes() == placed.tobytes()
