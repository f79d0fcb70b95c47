"""The hardware path without hardware: protocol, PDM decoding, the pyusb driver and
recorder against the emulated sensor (with faults), and the real eRTIS sample."""

import threading

import numpy as np
import pytest
from scipy.signal import freqz, upfirdn

import processing as P
from acousim.synth import PointReflectors, simulate_points
from hardware import (
    DeviceAccessDenied,
    DeviceNotFound,
    DeviceSettings,
    FrameError,
    Recorder,
    RecordingFailed,
    RtisDevice,
    build_frame,
    check_acquisition,
    decode,
    decode_frame,
    encode,
    parse_frame,
)
from hardware.emulator import EmulatedSensor, EmulatorBackend, recording_source
from hardware.pdm import (
    ENGINES,
    FILTERS,
    _pdm_kernel,
    decimation_filter,
    modulate,
    unpack_ticks,
)
from hardware.protocol import encode_command
from processing.base.errors import InputError
from tests import REPO

N_TICKS = 32768  # the smallest measurement keeps the tests fast


def test_command_and_frame_format():
    assert encode_command("G", 163840) == b"!G,163840,0,0\n"
    ticks = np.arange(8, dtype=np.uint32)
    f = parse_frame(build_frame(5, ticks), 8)
    assert f.index == 5 and np.array_equal(f.ticks, ticks)
    data = bytearray(build_frame(5, ticks))
    with pytest.raises(FrameError, match="short or long read"):
        parse_frame(bytes(data[:-4]), 8)
    data[-1] ^= 0xFF
    with pytest.raises(FrameError, match="bad footer"):
        parse_frame(bytes(data), 8)
    data[0] ^= 0xFF
    with pytest.raises(FrameError, match="bad header 0x"):
        parse_frame(bytes(data), 8)
    with pytest.raises(ValueError, match="unknown command"):
        encode_command("Z")


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name", FILTERS)
@pytest.mark.parametrize("n_ticks", [4000, 1237, 55])
def test_bit_k_is_channel_k_and_decoding_is_the_fir(engine, name, n_ticks):
    """Both engines equal the direct convolution of x = 2 b - 1 (zero outside the
    ticks), group delay removed, sampled every 10 ticks: at the ends too, and for a
    length that is not a multiple of 8 or 10."""
    rng = np.random.default_rng(n_ticks)
    ticks = rng.integers(0, 2**32, n_ticks, dtype=np.uint64).astype(np.uint32)
    bits = unpack_ticks(ticks)
    assert np.array_equal(bits[:, 7], (ticks >> 7) & 1)
    y = decode(ticks, [0, 7, 31], name, engine=engine)
    assert y.dtype == np.float32 and y.shape == (3, n_ticks // 10)
    h = decimation_filter(name)
    d = (len(h) - 1) // 2
    pad = (-d) % 10  # leading zeros that put the group delay on the decimated grid
    for row, ch in zip(y, [0, 7, 31]):
        x = np.concatenate([np.zeros(pad), 2.0 * bits[:, ch] - 1])
        ref = upfirdn(h, x, 1, 10)[(d + pad) // 10 :][: len(row)]  # scipy's polyphase
        np.testing.assert_allclose(row, ref, atol=2e-6)


def test_decimation_filters_meet_their_specification():
    w, H = freqz(decimation_filter(), worN=1 << 15, fs=4.5e6)
    pb, sb = np.abs(H[w <= 100e3]), np.abs(H[w >= 225e3])
    assert len(decimation_filter()) == 157 and abs(decimation_filter().sum() - 1) < 1e-12
    assert 20 * np.log10(pb.max() / pb.min()) < 0.01  # passband ripple, dB
    assert 20 * np.log10(sb.max()) < -80  # nothing above the output Nyquist survives
    rtis = decimation_filter("rtis")
    assert len(rtis) == 512
    w, H = freqz(rtis, worN=1 << 15, fs=4.5e6)
    assert abs(20 * np.log10(np.abs(H[np.argmin(np.abs(w - 100e3))])) + 6) < 0.1  # -6 dB


@pytest.mark.skipif(_pdm_kernel is None, reason="the C kernel is not built")
def test_portable_kernel_equals_the_simd_one():
    rng = np.random.default_rng(3)
    n8, stride, E = 257, 300, 5
    words = rng.integers(0, 2**32, 8 * n8, dtype=np.uint64).astype(np.uint32)
    fast, slow = np.zeros((32, stride), np.uint8), np.zeros((32, stride), np.uint8)
    _pdm_kernel.transpose(words, fast, stride, E)
    _pdm_kernel.transpose(words, slow, stride, E, True)
    assert np.array_equal(fast, slow)
    # row c, byte j, bit s is channel c at tick 8 j + s
    bits = np.unpackbits(fast[:, E : E + n8], axis=1, bitorder="little")
    assert np.array_equal(bits, unpack_ticks(words).T)
    T = rng.standard_normal((8, 257, 8)).astype(np.float32)
    rows = np.array([3, 0, 31], np.int32)
    a, b = np.empty((3, 8 * 20), np.float32), np.empty((3, 8 * 20), np.float32)
    _pdm_kernel.lut_fir(fast, stride, rows, T, 8, 257, 10, 20, a)
    _pdm_kernel.lut_fir(fast, stride, rows, T, 8, 257, 10, 20, b, True)
    assert np.array_equal(a, b)
    expect = sum(T[q, fast[3, 10 * 7 + q]].astype(float) for q in range(8))
    np.testing.assert_allclose(a[0, 56:64], expect, rtol=1e-5)
    with pytest.raises(ValueError, match="lut_fir: inconsistent sizes"):
        _pdm_kernel.lut_fir(fast, stride, rows, T, 8, 257, 10, 40, a)
    with pytest.raises(ValueError, match="not a multiple of 32"):
        _pdm_kernel.transpose(words[:9], fast, stride, E)


@pytest.mark.skipif(_pdm_kernel is None, reason="the C kernel is not built")
def test_sigma_delta_kernel_equals_the_numpy_loop():
    rng = np.random.default_rng(4)
    t = np.arange(20000) / 4.5e6
    x = 0.45 * np.sin(2 * np.pi * 40e3 * t) * rng.uniform(0.1, 1, (3, 1))
    x += 0.02 * rng.standard_normal(x.shape)
    bits = modulate(x)
    assert np.array_equal(bits, modulate(x, engine="fft"))
    # the bit stream carries the signal: its local mean follows x
    mean = np.convolve(2.0 * bits[0] - 1, np.ones(64) / 64, "same")
    assert np.corrcoef(mean[500:-500], x[0, 500:-500])[0, 1] > 0.97


def test_decode_refuses_bad_arguments():
    ticks = np.zeros(100, np.uint32)
    with pytest.raises(ValueError, match="unknown decimation filter 'hamming'"):
        decode(ticks, fir="hamming")
    with pytest.raises(ValueError, match="engine 'gpu'"):
        decode(ticks, engine="gpu")
    with pytest.raises(ValueError, match=r"channels must be in 0..31, got \[0, 32\]"):
        decode(ticks, [0, 32])
    from acousim.cli import PDM_FILTERS

    assert PDM_FILTERS == FILTERS


def _scene_recording():
    arr = P.urtis_v1()
    call = P.rtis_call()
    refl = PointReflectors([[1.2, 0.2, 0.05], [1.9, -0.5, 0.1]], 1.0)
    return simulate_points(refl, arr, call, 450e3, N_TICKS // 10), arr, call


def test_pdm_round_trip_noise():
    rec, arr, _ = _scene_recording()
    scale = 2 * np.abs(rec.samples).max()
    back = decode(encode(rec.samples, arr.channels, 450e3, scale), arr.channels) * scale
    snr = 10 * np.log10(np.sum(rec.samples**2) / np.sum((back - rec.samples) ** 2))
    # second-order sigma-delta at 4.5 MHz on sparse echoes at about -30 dB full scale:
    # about 22 dB with the default filter (the PDM noise of this emulator, stated in
    # docs/hardware.md); the vendor's filter lets more of it alias (about 19 dB)
    assert snr > 20
    back = decode(encode(rec.samples, arr.channels, 450e3, scale), arr.channels, "rtis")
    snr_rtis = 10 * np.log10(np.sum(rec.samples**2) / np.sum((back * scale - rec.samples) ** 2))
    assert 15 < snr_rtis < snr


@pytest.fixture
def emulated():
    rec, arr, call = _scene_recording()
    source = recording_source([rec], arr.channels)
    sensor = EmulatedSensor(source, n_ticks=N_TICKS)
    backend = EmulatorBackend(sensor)
    settings = DeviceSettings(n_ticks=N_TICKS, call=call.sampled(450e3))
    recorder = Recorder(
        lambda: RtisDevice(backend=backend), settings, arr, call, reconnect_timeout_s=5
    )
    return rec, source, sensor, backend, recorder


def test_simulate_pdm_driver_decode_round_trip(emulated):
    rec, source, sensor, backend, recorder = emulated
    out = recorder.acquire(count=2)
    assert [r.metadata["index"] for r in out] == [0, 1]
    x = out[0].samples * source.full_scale
    snr = 10 * np.log10(np.sum(rec.samples**2) / np.sum((x - rec.samples) ** 2))
    assert snr > 20  # the PDM noise, as above
    assert out[0].metadata["decimation_filter"] == "equiripple"
    # the driver detached the kernel driver, configured the sensor and uploaded the call
    assert not backend.kernel_driver[1]
    assert sensor.settings["G"] == N_TICKS and sensor.settings["E"] == 1125
    assert recorder.firmware == sensor.firmware
    # the echo is where it was simulated: matched-filter envelope peak within a sample
    template = out[0].waveform.sampled(450e3)
    from scipy.signal import hilbert

    def envelope_peak(x):
        return np.argmax(np.abs(hilbert(P.matched_filter(x, template), axis=1)), axis=1)

    assert np.max(np.abs(envelope_peak(out[0].samples) - envelope_peak(rec.samples))) <= 1


def test_emulated_recordings_say_so_in_memory_and_in_the_file(emulated, tmp_path):
    """A pipeline that keeps only real data must not take an emulated recording."""
    rec, _, _, _, recorder = emulated
    out = recorder.acquire(count=1)
    assert rec.provenance.kind == "simulated"  # the source
    assert out[0].provenance.kind == "emulated" and not out[0].provenance.simulated
    P.save_recordings(tmp_path / "e.h5", out)
    back = P.load_recording(tmp_path / "e.h5")
    assert back.provenance.kind == "emulated" and back.metadata["simulated"] is False
    assert "Recording(emulated" in repr(back)
    from acousim.dataset.info import describe

    assert "] emulated, array" in "\n".join(describe(tmp_path / "e.h5"))


@pytest.mark.parametrize("fault", ["drop", "corrupt", "stall", "short"])
def test_each_fault_is_detected_and_survived(emulated, fault):
    _, _, sensor, _, recorder = emulated
    recorder.acquire(count=1)
    sensor.inject(fault)
    out = recorder.acquire(count=2)
    assert len(out) == 2
    st = recorder.stats
    if fault == "drop":
        assert st.lost_indices == [1] and "lost [1]" in st.events[-1]
    elif fault in ("corrupt", "short"):
        assert st.corrupt == 1 and st.lost_indices == [1]
        assert ("bad header" if fault == "corrupt" else "short or long read") in st.events[0]
    else:
        # the late answer and frame of the timed-out trigger are drained, never read as
        # the next trigger's: that measurement is reported lost, the next ones are whole
        assert st.timeouts == 1 and st.lost_indices == [1]
        assert any("discarded" in e for e in st.events)
        assert [r.metadata["index"] for r in out] == [2, 3]


def test_a_frame_dropped_on_the_first_trigger_is_reported(emulated):
    _, _, sensor, _, recorder = emulated
    sensor.counter = 17  # whatever the sensor counted before: the recorder restarts it
    recorder.device.command("B", 17)
    recorder = Recorder(
        lambda: RtisDevice(backend=EmulatorBackend(sensor)),
        DeviceSettings(n_ticks=N_TICKS),
        recorder.array,
        recorder.call,
    )
    sensor.inject("drop")
    out = recorder.acquire(count=2)
    assert [r.metadata["index"] for r in out] == [1, 2]
    assert recorder.stats.lost_indices == [0]


def test_after_a_reconnect_the_indices_go_on(emulated):
    """A replugged sensor counts from 0 again: the recorder sets its counter back to
    the next index, so indices stay continuous and nothing is reported lost."""
    _, _, sensor, _, recorder = emulated
    recorder.acquire(count=3)
    sensor.inject("disconnect")
    threading.Timer(0.2, sensor.reconnect).start()
    out = recorder.acquire(count=3)
    assert [r.metadata["index"] for r in out] == [3, 4, 5]
    assert recorder.stats.lost_indices == [] and recorder.stats.counter_resets == []
    # and a counter that goes back anyway is reported, not hidden
    sensor.counter = 1
    recorder.acquire(count=1)
    assert recorder.stats.counter_resets == [(6, 1)]
    assert "went back from 6 to 1" in recorder.stats.events[-1]


@pytest.mark.parametrize("schedule", ["four stalls", "gone for good"])
def test_a_fatal_failure_keeps_the_measurements_taken(emulated, schedule):
    _, _, sensor, _, recorder = emulated
    recorder.reconnect_timeout_s = 0.3

    def fail_after_three(rec):
        if rec.metadata["index"] == 2:
            sensor.inject(*(["stall"] * 4 if schedule == "four stalls" else ["disconnect"]))

    with pytest.raises(RecordingFailed) as info:
        recorder.acquire(count=6, on_record=fail_after_three)
    assert [r.metadata["index"] for r in info.value.recordings] == [0, 1, 2]
    assert "after 3 measurement(s)" in str(info.value)
    reason = "4 attempts" if schedule == "four stalls" else "did not come back within 0.3 s"
    assert reason in str(info.value)


def test_a_sensor_that_does_not_answer_is_a_failure_not_a_traceback(emulated):
    _, _, sensor, backend, _ = emulated
    sensor.inject("stall")  # the first command's answer never comes
    with pytest.raises(RecordingFailed, match="did not answer while being configured"):
        Recorder(lambda: RtisDevice(backend=backend), DeviceSettings(n_ticks=N_TICKS), None, None)


@pytest.mark.parametrize(
    "count, duration, rate, key",
    [
        (0, None, 10, "--count"),
        (None, -1.0, 10, "--duration"),
        (None, float("nan"), 10, "--duration"),
        (None, float("inf"), 10, "--duration"),
        (2, None, 0.0, "--rate"),
        (None, None, 10, "--count/--duration"),
        (1, 1.0, 10, "--count/--duration"),
    ],
)
def test_acquisitions_that_cannot_record_are_refused(count, duration, rate, key):
    with pytest.raises(InputError, match=key):
        check_acquisition(count, duration, rate)


def test_the_emulator_refuses_an_array_the_link_cannot_carry():
    rec = P.Recording(np.zeros((64, 100)), 450e3, P.paper_8x8(), P.rtis_call())
    with pytest.raises(InputError, match="at most 32 microphones.*this array has 64"):
        recording_source([rec], np.arange(64))


def test_the_rest_of_a_short_frame_decodes_to_silence():
    """A recording shorter than the frame: the tail is the modulator's zero-signal
    stream, which decodes to (nearly) 0, not to the -1 of zero tick words."""
    rec, arr, _ = _scene_recording()
    short = rec.with_samples(rec.samples[:, -1000:])  # holds the echo at 1.2 m
    source = recording_source([short], arr.channels)
    words = source(0, N_TICKS)
    assert words.size == N_TICKS
    y = decode(words, arr.channels) * source.full_scale
    head = np.sqrt(np.mean(short.samples**2))
    tail = y[:, 1200:]  # past the filter's reach into the signal
    assert np.sqrt(np.mean(tail**2)) < 0.05 * head
    assert np.max(np.abs(np.mean(tail, axis=1))) < 1e-3 * source.full_scale
    # the zero-signal stream toggles: about half the bits of each channel set
    bits = unpack_ticks(words[20000:])[:, arr.channels]
    np.testing.assert_allclose(bits.mean(axis=0), 0.5, atol=0.01)


def test_disconnect_and_reconnect(emulated):
    _, _, sensor, _, recorder = emulated
    recorder.acquire(count=1)
    sensor.inject("disconnect")
    threading.Timer(0.2, sensor.reconnect).start()
    out = recorder.acquire(count=1)
    assert len(out) == 1 and recorder.stats.reconnects == 1
    assert "reconnected" in recorder.stats.events[-1]


def test_device_selection_by_serial_and_missing_device(emulated):
    _, _, sensor, backend, _ = emulated
    dev = RtisDevice(serial="EMU0001", backend=backend)
    assert dev.firmware_version() == sensor.firmware
    with pytest.raises(DeviceNotFound, match="serial 'NOPE'"):
        RtisDevice(serial="NOPE", backend=backend)
    with pytest.raises(DeviceNotFound, match="1234:5678"):
        RtisDevice(0x1234, 0x5678, backend=backend)
    # a user without the udev rule: pointed at docs/setup.md
    denied = EmulatorBackend(sensor, deny_access=True)
    with pytest.raises(DeviceAccessDenied, match="cannot be opened by this user.*docs/setup.md"):
        RtisDevice(backend=denied)


def test_real_ertis_sample_has_its_echo_near_3_2_m():
    from processing.sensor.rtisdev import sample_recording

    raw = np.frombuffer(sample_recording().read_bytes(), "<u4")
    assert raw.size == 163840
    rec = decode_frame(raw, P.ertis_v3d1(), P.rtis_call("default_25_50"))
    assert rec.samples.shape == (32, 16384)
    img = P.acoustic_image(
        rec,
        "das",
        P.ProcessingSettings(
            grid=P.Grid.degrees((-90, 90), (-60, 60), 2.0),
            range_limits_m=(1.0, 6.0),
            energy_fraction=0.3,
        ),
    )
    pk = img.peaks(-10)
    assert pk.range_m[0] == pytest.approx(3.20, abs=0.05)
    assert np.rad2deg(pk.azimuth_rad[0]) == pytest.approx(-8, abs=4)
    assert np.rad2deg(pk.elevation_rad[0]) == pytest.approx(2, abs=6)
    assert pk.level_db[1] < -3  # a single peak: everything else at least 3 dB down


def test_record_command_with_the_emulator(tmp_path, capsys, monkeypatch):
    """`record --emulate scenes/wall.toml` images the wall as the strongest peak (the
    frame's tail past the simulation is silence, not a false echo), and bad devices
    and arguments are one-line errors."""

    from acousim.cli import main
    from acousim.imaging.run import ImagingOptions, image_recordings

    scene = REPO / "scenes" / "wall.toml"
    out = tmp_path / "rec.h5"
    assert (
        main(
            ["record", "--emulate", str(scene), "--count", "2", "--rate", "100", "--out", str(out)]
        )
        == 0
    )
    recs = P.load_recordings(out)
    assert len(recs) == 2 and recs[0].array.name == "urtis_v1"
    assert recs[0].metadata["device"]["firmware"] > 0
    assert recs[0].n_samples == 16384  # a whole device frame, far past the 4 m scene
    tail = recs[0].samples[:, 12000:]
    assert np.sqrt(np.mean(tail**2)) < 0.01 * np.abs(recs[0].samples).max()
    # the wall, 2 m ahead and the sensor turned by 15 degrees: the strongest peak of
    # MUSIC-FBSS (the command line's imaging defaults) at 2 m (within one STFT window,
    # 9.8 cm; 1.95 m today), azimuth -15 degrees; not the false echo at 5.9 m that zero
    # tick words made
    img = image_recordings(recs[:1], ImagingOptions(methods=("music-fbss",)))[0]["music-fbss"]
    pk = img.peaks(-10)
    assert pk.range_m[0] == pytest.approx(2.0, abs=0.1)
    assert np.rad2deg(pk.azimuth_rad[0]) == pytest.approx(-15, abs=4)
    assert (
        main(["record", "--count", "1", "--out", str(tmp_path / "x.h5"), "--device", "dead:beef"])
        == 2
    )
    assert "no RTIS sensor with USB ID dead:beef" in capsys.readouterr().err
    monkeypatch.setenv("RTIS_VID", "zz")
    assert main(["record", "--count", "1", "--out", str(tmp_path / "x.h5")]) == 2
    assert "RTIS_VID = 'zz': expected a USB ID" in capsys.readouterr().err
    # refused by the parser (argparse's exit code 2), before anything starts
    for bad, key in (
        (["--count", "0"], "--count: '0': outside the allowed range"),
        (["--duration", "-1"], "--duration: '-1': outside the allowed range"),
        (["--duration", "nan"], "--duration: 'nan'"),
    ):
        with pytest.raises(SystemExit) as exit_:
            main(["record", *bad, "--out", str(tmp_path / "x.h5")])
        assert exit_.value.code == 2
        assert key in capsys.readouterr().err
    assert not (tmp_path / "x.h5").exists()


def test_record_command_keeps_the_measurements_when_the_sensor_fails(tmp_path, capsys, monkeypatch):
    """Four stalls in a row after the third measurement: the three are saved and the
    command exits 1 with the reason."""

    import hardware.emulator as emu
    from acousim.cli import main

    made = []
    real = emu.emulated_device

    def failing(*a, **kw):
        open_device, sensor = real(*a, **kw)
        made.append(sensor)
        source = sensor.source

        def source_then_fail(index, n):
            if index == 3:  # the fourth trigger and the three retries time out
                sensor.inject("stall", "stall", "stall", "stall")
            return source(index, n)

        sensor.source = source_then_fail
        return open_device, sensor

    monkeypatch.setattr(emu, "emulated_device", failing)
    scene = REPO / "scenes" / "wall.toml"
    out = tmp_path / "rec.h5"
    args = ["record", "--emulate", str(scene), "--count", "5", "--rate", "100", "--out", str(out)]
    assert main(args) == 1
    captured = capsys.readouterr()
    assert "3 measurement(s) written" in captured.out and "time-outs 4" in captured.out
    assert "the sensor failed after 3 measurement(s)" in captured.err
    assert [r.metadata["index"] for r in P.load_recordings(out)] == [0, 1, 2]


def test_files_from_the_rtisdev_wheel_are_checked(tmp_path, monkeypatch):
    """The pinned wheel and every file taken from it are checked whenever they are used:
    a tampered cached layout (aperture ten times too large) or wheel is refused."""
    import shutil

    import scipy.io

    from processing.sensor import rtisdev

    wheel = rtisdev.wheel_path()  # the real cache (downloads once if empty)
    monkeypatch.setenv("ACOUSIM_CACHE", str(tmp_path))
    folder = tmp_path / f"rtisdev-{rtisdev.VERSION}"
    folder.mkdir()
    shutil.copy(wheel, folder / wheel.name)
    layout = rtisdev.layout_file("eRTIS_v3D1")
    assert layout.is_relative_to(tmp_path)
    data = scipy.io.loadmat(layout)
    key = next(k for k in data if not k.startswith("__"))
    data[key] = data[key] * 10
    scipy.io.savemat(layout, {key: data[key]})
    with pytest.raises(rtisdev.IntegrityError, match="mic_coordinates.mat: sha256 .* not the"):
        rtisdev.layout_file("eRTIS_v3D1")
    layout.unlink()  # deleting it fetches the right one again from the wheel
    assert rtisdev.layout_file("eRTIS_v3D1").read_bytes() != b""
    rtisdev._verified.clear()  # as in a new process: the wheel is checked when first opened
    with open(folder / wheel.name, "r+b") as f:  # one flipped byte in the wheel
        f.seek(1000)
        b = f.read(1)
        f.seek(1000)
        f.write(bytes([b[0] ^ 1]))
    with pytest.raises(rtisdev.IntegrityError, match="pinned rtisdev 2.15.1 wheel"):
        rtisdev.sample_recording()


@pytest.mark.parametrize("moment", ["simulating", "measuring", "writing"])
def test_record_command_interrupted(tmp_path, capsys, monkeypatch, moment):
    """Ctrl-C while the emulated scene is simulated, while measuring (the third
    trigger) or while the file is written: exit 130, and either no file at all or a
    loadable one with every complete measurement."""

    import acousim.simulator as sim_mod
    import hardware.emulator as emu
    import processing.formats.native as rec_mod
    from acousim.cli import main

    def boom(*a, **k):
        raise KeyboardInterrupt

    if moment == "simulating":
        monkeypatch.setattr(sim_mod.Simulator, "simulate_pose", boom)
    elif moment == "measuring":
        real = emu.emulated_device

        def interrupting(*a, **kw):
            open_device, sensor = real(*a, **kw)
            source = sensor.source

            def source_then_interrupt(index, n):
                if index == 2:
                    raise KeyboardInterrupt
                return source(index, n)

            sensor.source = source_then_interrupt
            return open_device, sensor

        monkeypatch.setattr(emu, "emulated_device", interrupting)
    else:
        monkeypatch.setattr(rec_mod, "_write_one", boom)
    scene = REPO / "scenes" / "wall.toml"
    out = tmp_path / "rec.h5"
    args = ["record", "--emulate", str(scene), "--count", "4", "--rate", "100", "--out", str(out)]
    assert main(args) == 130
    if moment == "measuring":
        assert "2 measurement(s) written" in capsys.readouterr().out
        assert [r.metadata["index"] for r in P.load_recordings(out)] == [0, 1]
        assert [p.name for p in tmp_path.iterdir()] == ["rec.h5"]
    else:
        assert list(tmp_path.iterdir()) == []


def test_acquisition_ranges_are_the_declared_ones():
    """--count, --duration and --rate are declared once (hardware.Acquisition): the
    library's check and the command line refuse the same values, naming the option."""
    from acousim.cli import build_parser
    from hardware import Acquisition

    assert Acquisition().rate_hz == 10.0  # the one home of the command line's default
    for count, duration, rate, key in (
        (10**9 + 1, None, 10, "--count"),
        (None, 1e-4, 10, "--duration"),
        (None, 1.0, 2e4, "--rate"),
    ):
        with pytest.raises(InputError, match=key):
            check_acquisition(count, duration, rate)
    check_acquisition(10**9, None, None)  # the largest count, as fast as the sensor answers
    check_acquisition(None, 1e-3, 1e4)
    with pytest.raises(InputError, match="rate_hz"):
        Acquisition(rate_hz=0.0)
    with pytest.raises(SystemExit):
        build_parser().parse_args(["record", "--rate", "2e4", "--out", "x.h5"])


def test_import_hardware_gives_its_modules():
    """docs/hardware.md's `import hardware` then `hardware.emulator.emulated_device`:
    the emulator module is an attribute, imported on first use (not by the import)."""
    import subprocess
    import sys

    code = (
        "import sys, hardware\n"
        "assert 'hardware.emulator' not in sys.modules\n"
        "assert callable(hardware.emulator.emulated_device)\n"
        "assert callable(hardware.recorder.Recorder) and callable(hardware.pdm.decode)\n"
        "try:\n    hardware.no_such_module\nexcept AttributeError:\n    print('ok')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=False
    )
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


def test_a_file_taken_from_the_wheel_inside_a_commands_group_of_outputs(tmp_path, monkeypatch):
    """A command that renames its outputs together at its end (``acousim compare
    rtisdev-sample`` on an empty cache) still gets the sample: the cache's file is in
    place when it is taken, not held back with the command's outputs; and an output
    of the group still waits for the group's end."""
    import shutil

    from processing.base.atomic import committed_together, write_bytes
    from processing.sensor import rtisdev

    wheel = rtisdev.wheel_path()  # the real cache (downloads once if empty)
    monkeypatch.setenv("ACOUSIM_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "cache" / f"rtisdev-{rtisdev.VERSION}"
    folder.mkdir(parents=True)
    shutil.copy(wheel, folder / wheel.name)
    output = tmp_path / "out.txt"
    with committed_together():
        write_bytes(output, b"the command's output")
        sample = rtisdev.sample_recording()
        assert sample.is_relative_to(tmp_path) and sample.stat().st_size > 0
        assert not output.exists()  # the group's own file: renamed at the end
    assert output.read_bytes() == b"the command's output"
    assert sample.read_bytes()[:4] == rtisdev.sample_recording().read_bytes()[:4]
