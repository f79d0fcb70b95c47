"""``acousim record``: record measurements from an RTIS sensor over USB.

Record measurements from a real RTIS sensor (pyusb) or an emulated one, decode their PDM
frames and write them to an HDF5 file. Ctrl-C keeps every complete measurement.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from acousim.cli.common import (
    UsageError,
    add_command,
    add_seed,
    choice,
    from_start,
    load_scene,
    output_file,
    preload_simulation,
    progress,
    stop_if_interrupted,
)
from acousim.cli.options import add_declared
from processing.base.errors import InputError
from processing.sensor.rtis import RTIS_SAMPLE_RATE_HZ

# hardware.pdm.FILTERS, repeated so that the parser does not import scipy.signal (tested)
PDM_FILTERS = ("equiripple", "rtis")
# processing.PRESETS and the RTIS call presets, repeated for the same reason (tested)
ARRAY_PRESETS = ("ertis_v3d1", "paper_8x8", "urtis_v1")
CALL_PRESETS = ("default_20_80", "default_25_50")
#: the declarations of --count, --duration and --rate
ACQUISITION = "hardware.recorder:Acquisition"


def add_array(
    parser, what: str, *, default: str | None = "ertis_v3d1", default_text: str | None = None
) -> None:
    """The --array option: one of ARRAY_PRESETS, described as `what`; `default` when not
    given, said in the help as `default_text` (default: its name)."""
    parser.add_argument(
        "--array",
        default=default,
        type=choice("array preset", ARRAY_PRESETS),
        help=f"{what}: {', '.join(ARRAY_PRESETS)} ({default_text or f'default: {default}'})",
    )


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument("--device", help="USB VID:PID in hex (default: $RTIS_VID:$RTIS_PID)")
    p.add_argument("--serial", help="serial number of the sensor to use")
    add_declared(p, "--count", ACQUISITION, "count")
    add_declared(p, "--duration", ACQUISITION, "duration_s")
    add_declared(p, "--rate", ACQUISITION, "rate_hz")
    add_array(
        p,
        "the sensor's microphone array (its channel map and layout)",
        default=None,
        default_text="default: ertis_v3d1; with --emulate, the scene's",
    )
    p.add_argument(
        "--call",
        type=choice("RTIS call preset", CALL_PRESETS),
        help=f"the call the sensor emits: {', '.join(CALL_PRESETS)} (default: "
        "default_25_50; with --emulate, the scene's)",
    )
    p.add_argument(
        "--emulate",
        metavar="SCENE",
        help="record from an emulated sensor streaming this scene's simulation (a scene "
        "file or a bundled scene's name), with --array and --call (when given) in place "
        "of the scene's, at the scene's speed of sound; a scene's poses are measured in "
        "turn, each round with its own noise (seeded by the scene's seed, or --seed)",
    )
    add_seed(p)
    p.add_argument(
        "--filter",
        choices=PDM_FILTERS,
        default="equiripple",
        help="PDM decimation filter: equiripple (default, 157 taps, >80 dB alias "
        "rejection) or rtis (the vendor host's 512-tap FIR, 2-3x slower)",
    )
    p.add_argument(
        "--out",
        required=True,
        help="output file (.h5); its missing folders are made, and removed again if "
        "still empty when the run fails or is interrupted; an existing file is replaced "
        "only if it is a recording file acousim wrote",
    )


def emulated_scene(scene, array: str | None, call: str | None, seed: int | None = None):
    """The scene with the sensor's `array` and `call` presets and the noise `seed` (each
    None: the scene's) in place of its own, as on a real sensor where --array and
    --call say which sensor is plugged in and what it emits."""
    import dataclasses

    import processing as P

    changes = {}
    if array is not None:
        changes["array"] = P.preset(array)
    if call is not None:
        changes["call"] = P.rtis_call(call)
    if changes:
        scene = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, **changes))
    if seed is not None:
        scene = dataclasses.replace(
            scene, simulation=dataclasses.replace(scene.simulation, seed=seed)
        )
    return scene


def repetition_seed(scene_seed: int, repetition: int) -> int:
    """The noise seed of the `repetition`-th (1, 2, ...) measurement of a scene's pose
    by the emulated sensor (the 0th is the scene's own: its seed), drawn from
    (scene seed, repetition): the same command, the same bytes."""
    import numpy as np

    return int(np.random.SeedSequence([scene_seed, repetition, 2]).generate_state(1)[0])


def emulation_recordings(scene, count: int | None) -> tuple[list, Callable]:
    """What an emulated sensor streams: the scene's first poses (at most `count`, else
    10) simulated at the sensor's 450 kHz, as `acousim simulate` gives them, and
    ``repeat(k, r)``: pose k measured again (repetition r >= 1), with its own noise
    (:func:`repetition_seed`)."""
    from acousim.simulator import Simulator

    if scene.sensor.sample_rate_hz != RTIS_SAMPLE_RATE_HZ:
        raise UsageError(
            f"--emulate {scene.source}: the scene samples at "
            f"{scene.sensor.sample_rate_hz:g} Hz; the sensor at {RTIS_SAMPLE_RATE_HZ:g}"
        )
    n = min(len(scene.sensor.poses), count or 10)
    try:
        sim = Simulator(scene)
        out = []
        bar = progress("simulate", "pose")
        for i in range(n):
            stop_if_interrupted()
            out.append(sim.simulate_pose(scene.sensor.poses[i], i))
            bar(i + 1, n)
    except InputError as exc:  # an unreadable mesh, a scene the simulator refuses
        raise UsageError(f"--emulate {scene.source}: {exc}") from None

    def repeat(k: int, r: int):
        seed = repetition_seed(scene.simulation.seed, r)
        return sim.simulate_pose(scene.sensor.poses[k], k, seed=seed)

    return out, repeat


def _recorder(args: argparse.Namespace):
    """The Recorder for the real or emulated sensor the arguments name."""
    import processing as P
    from hardware import DeviceSettings, Recorder
    from hardware.device import RtisDevice, find_ids, parse_usb_id
    from hardware.emulator import check_channels, emulated_device

    if args.emulate:
        scene = emulated_scene(load_scene(args.emulate), args.array, args.call, args.seed)
        array, call = scene.sensor.array, scene.sensor.call  # the air: the recordings'
        try:  # before simulating
            check_channels(array.channels)
        except InputError as exc:
            raise UsageError(
                f"--emulate {args.emulate}: array {array.name!r}: {exc.reason}"
            ) from None
        preload_simulation()
        recs, repeat = emulation_recordings(scene, args.count)
        open_device, _ = emulated_device(recs, array.channels, serial=args.serial, repeat=repeat)
    else:
        if args.seed is not None:
            raise UsageError(
                "a real sensor's noise is not seeded (--seed goes with --emulate)",
                key="--seed",
                value=args.seed,
            )
        vid, pid = parse_usb_id(args.device) if args.device else find_ids()
        array = P.preset(args.array or "ertis_v3d1")
        call = P.rtis_call(args.call or "default_25_50")

        def open_device():
            return RtisDevice(vid, pid, serial=args.serial)

    return Recorder(
        open_device,
        DeviceSettings(call=call.sampled(RTIS_SAMPLE_RATE_HZ)),
        array,
        call,
        fir=args.filter,
    )


def run(args: argparse.Namespace) -> int:
    import processing as P
    from hardware import (
        Acquisition,
        DeviceNotFound,
        RecordingFailed,
        RecordingInterrupted,
        check_acquisition,
    )
    from processing.base import interrupt

    rate = Acquisition().rate_hz if args.rate is None else args.rate  # the declared default
    try:
        check_acquisition(args.count, args.duration, rate)
        out = output_file("--out", args.out, "recordings")
        recorder = _recorder(args)
    except (InputError, DeviceNotFound) as exc:
        raise UsageError(str(exc)) from None
    except RecordingFailed as exc:
        print(f"acousim record: error: {exc.reason}; nothing recorded", file=sys.stderr)
        return 1
    bar = progress("record", "measurement", checkpoint=False)
    kept: list = []

    def keep(rec) -> None:
        kept.append(rec)
        bar(len(kept), args.count)  # no count (--duration): count and rate, no time left

    interrupted, failure = False, None
    try:
        recorder.acquire(args.count, args.duration, rate, on_record=keep, stop=interrupt.requested)
    except RecordingInterrupted:
        # the first Ctrl-C stops the acquisition; what was kept is saved (a second
        # Ctrl-C during the save leaves --out as it was)
        interrupt.consume()
        interrupted = True
    except RecordingFailed as exc:
        failure = exc
    bar.finish()
    if kept:
        P.save_recordings(out, kept)
    print(_summary(out, kept, recorder.stats, interrupted, failure) + f" {from_start()}")
    if interrupted:
        print(
            f"acousim record: interrupted; {len(kept)} complete measurement(s) kept",
            file=sys.stderr,
        )
    if failure:
        print(f"acousim record: error: {failure}", file=sys.stderr)
        return 1
    return 130 if interrupted else 0


def _summary(out, kept, st, interrupted: bool, failure) -> str:
    return (
        (f"{len(kept)} measurement(s) written to {out}" if kept else "no measurement taken")
        + (" (interrupted)" if interrupted else "")
        + (" (the sensor failed)" if failure else "")
        + f"; lost {len(st.lost_indices)}"
        + (f" (indices {st.lost_indices[:10]})" if st.lost_indices else "")
        + f", corrupt {st.corrupt}, time-outs {st.timeouts}, reconnects {st.reconnects}"
        + (f", counter resets {len(st.counter_resets)}" if st.counter_resets else "")
    )
