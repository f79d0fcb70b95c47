"""`acousim record --emulate` as a user of the real sensor runs it: the scene's speed of
sound, its own noise in every repetition, --array and --call honoured; and raw tick
files read with a clear error."""

import numpy as np
import pytest
from scipy.signal import hilbert

import processing as P
from hardware import read_ticks
from processing.base.errors import InputError

FS = 450e3
POINT = np.array([1.5, 0.1, 0.05])  # m, the sensor at the origin looking along x


def _scene(tmp_path, *, snr_db: str = "inf", name: str = "point.toml"):
    path = tmp_path / name
    path.write_text(
        f"""[scene]
name = "point"
[sensor]
array = "urtis_v1"
call = "default_25_50"
sample_rate_hz = 450000
direct_path = false
[sensor.pose]
position_m = [0.0, 0.0, 0.0]
[simulation]
max_range_m = 3.0
snr_db = {snr_db}
seed = 5
[[points]]
position_m = [{POINT[0]}, {POINT[1]}, {POINT[2]}]
strength = 1.0
"""
    )
    return path


def _record(scene, out, *extra: str) -> list[P.Recording]:
    from acousim.cli import main

    args = ["record", "--emulate", str(scene), "--rate", "1000", "--out", str(out), *extra]
    assert main(args) == 0
    return P.load_recordings(out)


def _rtis_call(f_hi: float, f_lo: float, T: float = 2.5e-3) -> np.ndarray:
    """The RTIS call built here from the facts: a hyperbolic sweep from `f_hi` down to
    `f_lo` (Hz), its period linear in time over `T` (s), 10 % Hann tapers, at 450 kHz."""
    n = int(round(T * FS))
    t = np.arange(n) / FS
    k = 1 / f_lo - 1 / f_hi
    call = np.sin(2 * np.pi * T / k * np.log1p(t * f_hi * k / T))
    m = n // 10
    w = np.hanning(2 * m)
    call[:m] *= w[:m]
    call[-m:] *= w[m:]
    return call


def _echo_delay_s(rec: P.Recording) -> np.ndarray:
    """Per microphone (M,), the delay (s) of the matched filter's envelope peak after
    the emission (parabolic interpolation), with the call built from the facts."""
    call = _rtis_call(max(rec.waveform.band_hz), min(rec.waveform.band_hz))
    x = rec.samples[:, rec.emission_index :]
    spec = np.fft.rfft(x, 2 * x.shape[1]) * np.conj(np.fft.rfft(call, 2 * x.shape[1]))
    env = np.abs(hilbert(np.fft.irfft(spec)[:, : x.shape[1]], axis=1))
    i = np.argmax(env, axis=1)
    rows = np.arange(len(i))
    y0, y1, y2 = env[rows, i - 1], env[rows, i], env[rows, i + 1]
    return (i + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)) / FS


def test_an_emulated_recording_carries_the_scenes_speed_of_sound(tmp_path):
    """The scene's air (20 °C, 50 % by default): 343.99 m/s (Cramer 1993, the value
    ISO 9613-1's users quote), not the nominal 343; the echo's delay read with the
    file's c gives the reflector's path back to a millimetre (343 would be 4 mm out)."""
    rec = _record(_scene(tmp_path), tmp_path / "e.h5", "--count", "1")[0]
    assert rec.speed_of_sound_m_s == pytest.approx(343.99, abs=0.01)
    path_m = np.linalg.norm(POINT) + np.linalg.norm(POINT - rec.array.positions_m, axis=1)
    measured_m = rec.speed_of_sound_m_s * _echo_delay_s(rec)
    assert np.median(np.abs(measured_m - path_m)) < 1e-3


def test_repeated_measurements_of_one_pose_have_their_own_noise(tmp_path, capsys):
    """A one-pose scene measured three times: three noises, uncorrelated where there
    is only noise (before the echo), of one level; the same command and seed again
    give the same samples, another seed others; a real sensor takes no seed."""
    scene = _scene(tmp_path, snr_db="10")
    recs = _record(scene, tmp_path / "a.h5", "--count", "3")
    again = _record(scene, tmp_path / "b.h5", "--count", "3", "--seed", "5")  # the scene's
    assert all(np.array_equal(a.samples, b.samples) for a, b in zip(recs, again))
    other = _record(scene, tmp_path / "c.h5", "--count", "3", "--seed", "6")
    assert not any(np.array_equal(a.samples, b.samples) for a, b in zip(recs, other))
    # the first round is the scene's own simulation (acousim simulate's), the others not
    from acousim.cli import main

    assert main(["simulate", str(scene), "--out", str(tmp_path / "s.h5")]) == 0
    sim = P.load_recordings(tmp_path / "s.h5")[0].samples
    n = sim.shape[1]
    match = [np.corrcoef(r.samples[:, :n].ravel(), sim.ravel())[0, 1] for r in recs]
    # (0.94: the PDM's error alone; 0.63 the echo's share of the samples: its noise
    # independent of the simulation's)
    assert match[0] > 0.9 and max(match[1:]) < 0.75
    bad = ["record", "--seed", "3", "--count", "1", "--out", str(tmp_path / "x.h5")]
    assert main(bad) == 2
    assert "--seed = 3: a real sensor's noise is not seeded" in capsys.readouterr().err
    quiet = [r.samples[:, 300:4000].ravel() for r in recs]  # the echo starts at 3900+
    for i in range(3):
        for j in range(i):
            assert abs(np.corrcoef(quiet[i], quiet[j])[0, 1]) < 0.05
            assert np.std(quiet[i]) / np.std(quiet[j]) == pytest.approx(1, abs=0.1)


def _band_fraction(x: np.ndarray, lo: float, hi: float) -> float:
    """The fraction of the energy of `x` (..., T) at 15-90 kHz that lies in [lo, hi) Hz."""
    spec = np.abs(np.fft.rfft(x, 1 << 15, axis=-1)) ** 2
    f = np.fft.rfftfreq(1 << 15, 1 / FS)
    return float(spec[..., (f >= lo) & (f < hi)].sum() / spec[..., (f >= 15e3) & (f < 90e3)].sum())


def test_array_and_call_are_those_of_the_command_line(tmp_path):
    """--array ertis_v3d1 --call default_20_80 with --emulate: the emulated sensor is an
    eRTIS (32 microphones over about 66 x 38 mm) emitting the 20-80 kHz call: the
    echo's share of energy in 55-80 kHz is that of the call built from the facts (10 %),
    less the air's absorption over the 3 m, stronger there (at most 1/3 of it lost);
    the 25-50 kHz call puts none there."""
    scene = _scene(tmp_path)
    rec = _record(
        scene, tmp_path / "e.h5", "--count", "1", "--array", "ertis_v3d1", "--call", "default_20_80"
    )[0]
    assert rec.array.name == "ertis_v3d1" and rec.array.n_mics == 32
    span_mm = np.ptp(rec.array.positions_m, axis=0) * 1e3
    assert span_mm[1] == pytest.approx(66, abs=8) and span_mm[2] == pytest.approx(38, abs=8)
    assert sorted(rec.waveform.band_hz) == [20e3, 80e3]
    share = _band_fraction(_rtis_call(80e3, 20e3), 55e3, 80e3)
    assert share == pytest.approx(0.10, abs=0.01)  # no more the 1/f^2 law's 15 %: the tapers
    assert share / 3 < _band_fraction(rec.samples, 55e3, 80e3) < share
    default = _record(scene, tmp_path / "d.h5", "--count", "1")[0]
    assert default.array.name == "urtis_v1" and sorted(default.waveform.band_hz) == [25e3, 50e3]
    assert _band_fraction(default.samples, 55e3, 80e3) < 0.01


def test_an_array_the_link_cannot_carry_is_refused_before_simulating(tmp_path, capsys):
    from acousim.cli import main

    out = tmp_path / "x.h5"
    args = ["record", "--emulate", str(_scene(tmp_path)), "--array", "paper_8x8"]
    assert main([*args, "--count", "1", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert "array 'paper_8x8': the RTIS link carries at most 32 microphones" in captured.err
    assert "this array has 64" in captured.err and "simulate" not in captured.out + captured.err
    assert not out.exists()


@pytest.mark.parametrize(
    "size, words",
    [(1001, "1001 bytes"), (0, "0 bytes"), (4000, "4000 bytes = 1000 tick words")],
)
def test_a_raw_file_of_the_wrong_size_is_refused_by_name_and_size(tmp_path, size, words):
    path = tmp_path / "raw.bin"
    path.write_bytes(bytes(size))
    with pytest.raises(InputError) as err:
        read_ticks(path)
    assert str(err.value).startswith(f"{path}: {words}")
    assert "\n" not in str(err.value)


def test_a_raw_file_reads_as_little_endian_words(tmp_path):
    words = np.arange(2 * 32768, dtype=np.uint32) * 65537
    path = tmp_path / "raw.bin"
    head = b"".join(int(w).to_bytes(4, "little") for w in words[:8])  # by hand
    path.write_bytes(head + words[8:].astype("<u4").tobytes())
    assert np.array_equal(read_ticks(path), words)
    with pytest.raises(InputError, match="no such file"):
        read_ticks(tmp_path / "missing.bin")


def test_in_python_the_emulated_sensor_gives_its_recordings_air(tmp_path):
    """emulated_device + Recorder: the recordings carry the streamed recordings' c
    (here 331.3 m/s, dry air at 0 °C), not the nominal 343; a sensor that does not
    know its air (a real one) gives 343; recordings of two airs are refused."""
    from acousim.synth import PointReflectors, simulate_points
    from hardware import DeviceSettings, Recorder
    from hardware.emulator import emulated_device

    arr, call = P.urtis_v1(), P.rtis_call()
    rec = simulate_points(
        PointReflectors([[1.2, 0.2, 0.05]], 1.0), arr, call, FS, 3277, speed_of_sound_m_s=331.3
    )
    settings = DeviceSettings(n_ticks=32768, call=call.sampled(FS))
    open_device, sensor = emulated_device([rec], arr.channels, n_ticks=32768)
    assert (
        Recorder(open_device, settings, arr, call).acquire(count=1)[0].speed_of_sound_m_s == 331.3
    )
    sensor.speed_of_sound_m_s = None  # as a real sensor: it does not know the air
    assert Recorder(open_device, settings, arr, call).acquire(count=1)[0].speed_of_sound_m_s == 343
    other = simulate_points(PointReflectors([[1.2, 0.2, 0.05]], 1.0), arr, call, FS, 3277)
    with pytest.raises(InputError, match=r"speed_of_sound_m_s = \[331.3, 343.0\]"):
        emulated_device([rec, other], arr.channels)
