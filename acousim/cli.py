"""The ``acousim`` command line: a thin layer that parses, calls the library, reports.

Errors in what the user gave (a file, a key, a value) are reported on one line with
exit code 2; files are written under a temporary name and renamed when complete, so
an error or Ctrl-C leaves no partial output.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

# hardware.pdm.FILTERS, repeated so that the parser does not import scipy.signal (tested)
PDM_FILTERS = ("equiripple", "rtis")


class UsageError(Exception):
    """Bad input from the user: printed on one line, exit code 2."""


def bundled_scenes() -> Path:
    """The scenes/ folder of the source tree."""
    return Path(__file__).resolve().parent.parent / "scenes"


def _progress(desc: str):
    """A tqdm progress callback: shown after a second, and only on a terminal."""
    from tqdm import tqdm

    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(
                total=total, desc=desc, delay=1.0, disable=not sys.stderr.isatty(), leave=False
            )
        bar.update(done - bar.n)
        if done == total:
            bar.close()

    return update


def _writable_dir(path: str | Path) -> Path:
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".acousim-write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise UsageError(
            f"output directory {str(out)!r} cannot be written ({exc.strerror})"
        ) from None
    return out


def _load_scene(path: str | Path):
    from acousim.scene import SceneError, load_scene

    try:
        return load_scene(path)
    except SceneError as exc:
        raise UsageError(str(exc)) from None


def _parse_indices(option: str, text: str | None) -> list[int] | None:
    if not text:
        return None
    out: list[int] = []
    try:
        for part in text.split(","):
            a, _, b = part.partition(":")
            out.extend(range(int(a), int(b)) if b else [int(a)])
    except ValueError:
        raise UsageError(
            f"{option} {text!r}: expected indices like '0,3,5' or a range '0:10'"
        ) from None
    return out


def _simulate(scene, poses, seed):
    from acousim.simulator import Simulator

    if seed is not None:
        scene = dataclasses.replace(
            scene, simulation=dataclasses.replace(scene.simulation, seed=seed)
        )
    try:
        recs = Simulator(scene).run(poses, progress=_progress("simulate"))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    for r in recs:
        if r.metadata.get("n_paths", 0) == 0:
            raise UsageError(
                f"scene {scene.name!r}: no echo reaches the sensor at pose "
                f"{r.metadata.get('pose_index')} (nothing within "
                f"{scene.simulation.max_range_m} m)"
            )
    return recs


def _cmd_simulate(args: argparse.Namespace) -> int:
    import processing as P

    scene = _load_scene(args.scene)
    out = Path(args.out or f"{scene.name}.h5")
    _writable_dir(out.parent)
    t0 = time.perf_counter()
    recs = _simulate(scene, _parse_indices("--poses", args.poses), args.seed)
    P.save_recordings(out, recs)
    print(
        f"{len(recs)} recording(s) of {scene.name!r} written to {out} "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return 0


def _cmd_image(args: argparse.Namespace) -> int:
    import processing as P
    from acousim.imaging import ImagingOptions, image_recordings, write_pictures

    methods = tuple(m.strip() for m in args.method.split(",") if m.strip())
    try:
        given = {"energy_fraction": args.energy_fraction, "min_range_m": args.min_range}
        options = ImagingOptions(  # unset options keep ProcessingSettings' defaults
            methods=methods,
            step_deg=args.step,
            max_range_m=args.max_range,
            **{k: v for k, v in given.items() if v is not None},
        )
    except ValueError as exc:
        raise UsageError(f"--method {args.method!r}: {exc}") from None
    out = _writable_dir(args.out)
    try:
        recs = P.load_recordings(args.file)
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None
    index = _parse_indices("--index", args.index)
    if index is not None:
        bad = [i for i in index if not 0 <= i < len(recs)]
        if bad:
            raise UsageError(f"--index {bad}: the file holds {len(recs)} recording(s)")
        recs = [recs[i] for i in index]
    try:
        images = image_recordings(recs, options, _progress("image"))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    files = write_pictures(
        recs,
        images,
        out,
        options,
        render_3d=not args.no_3d,
        animation=not args.no_animation,
        progress=_progress("animate"),
    )
    for f in files:
        print(f"  {f}")
    return 0


def _cmd_scenes(args: argparse.Namespace) -> int:
    from acousim.scene import SceneError, load_scene

    for f in sorted(bundled_scenes().glob("*.toml")):
        try:
            sc = load_scene(f)
        except SceneError as exc:
            print(f"{f.name}: invalid ({exc})")
            continue
        print(
            f"{f.name:16s} {sc.sensor.array.name}, {len(sc.sensor.poses)} pose(s): {sc.description}"
        )
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    import processing as P
    from acousim.imaging import ImagingOptions, image_recordings, write_pictures

    t0 = time.perf_counter()
    out = _writable_dir(args.out)
    scene = _load_scene(bundled_scenes() / "corridor.toml")
    recs = _simulate(scene, None, args.seed)
    P.save_recordings(out / "corridor.h5", recs)
    t1 = time.perf_counter()
    options = ImagingOptions()
    images = image_recordings(recs, options, _progress("image"))
    t2 = time.perf_counter()
    files = [out / "corridor.h5"] + write_pictures(
        recs, images, out, options, progress=_progress("animate")
    )
    print(
        f"corridor drive: {len(recs)} poses simulated in {t1 - t0:.1f} s, imaged in "
        f"{t2 - t1:.1f} s, pictures in {time.perf_counter() - t2:.1f} s:"
    )
    for f in files:
        print(f"  {f}")
    return 0


def _cmd_record(args: argparse.Namespace) -> int:
    import processing as P
    from hardware import DeviceNotFound, DeviceSettings, Recorder, RecordingInterrupted
    from hardware.device import RtisDevice

    if (args.count is None) == (args.duration is None):
        raise UsageError("give exactly one of --count N or --duration S")
    out = Path(args.out)
    _writable_dir(out.parent)
    try:
        array, call = P.preset(args.array), P.rtis_call(args.call)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    backend = None
    vid = pid = None
    if args.device:
        try:
            vid, pid = (int(v, 16) for v in args.device.split(":"))
        except ValueError:
            raise UsageError(f"--device {args.device!r}: expected VID:PID in hex") from None
    if args.emulate:
        from acousim.simulator import Simulator
        from hardware.emulator import EmulatedSensor, EmulatorBackend, recording_source

        scene = _load_scene(args.emulate)
        if scene.sensor.sample_rate_hz != 450e3:
            raise UsageError(
                f"--emulate {args.emulate}: the scene samples at "
                f"{scene.sensor.sample_rate_hz:g} Hz; the sensor at 450000"
            )
        sim = Simulator(scene)
        n = min(len(scene.sensor.poses), args.count or 10)
        recs = [sim.simulate_pose(scene.sensor.poses[i], i) for i in range(n)]
        array, call = scene.sensor.array, scene.sensor.call
        backend = EmulatorBackend(EmulatedSensor(recording_source(recs, array.channels)))
        vid, pid = backend.vid, backend.pid
    settings = DeviceSettings(call=call.sampled(450e3))
    try:
        recorder = Recorder(
            lambda: RtisDevice(vid, pid, serial=args.serial, backend=backend),
            settings,
            array,
            call,
            fir=args.filter,
        )
    except DeviceNotFound as exc:
        raise UsageError(str(exc)) from None
    bar = _progress("record")
    kept: list = []

    def keep(rec) -> None:
        kept.append(rec)
        if args.count:
            bar(len(kept), args.count)

    interrupted = False
    try:
        recorder.acquire(args.count, args.duration, args.rate, on_record=keep)
    except RecordingInterrupted:
        interrupted = True
    if kept:
        P.save_recordings(out, kept)
    st = recorder.stats
    print(
        f"{len(kept)} measurement(s) written to {out}"
        + (" (interrupted)" if interrupted else "")
        + f"; lost {len(st.lost_indices)}, corrupt {st.corrupt}, time-outs {st.timeouts}, "
        f"reconnects {st.reconnects}"
    )
    return 130 if interrupted else 0


def _load_real(args: argparse.Namespace, c: float):
    import processing as P

    if args.real == "rtisdev-sample" or args.real.endswith(".bin"):
        from hardware import decode_frame
        from processing.rtisdev import sample_recording

        path = sample_recording() if args.real == "rtisdev-sample" else Path(args.real)
        if not Path(path).is_file():
            raise UsageError(f"{path}: no such file")
        raw = np.frombuffer(Path(path).read_bytes(), "<u4")
        if raw.size == 0 or raw.size % 32768:
            raise UsageError(f"{path}: {raw.size} tick words, not a multiple of 32768")
        try:
            array, call = P.preset(args.array), P.rtis_call(args.call)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        return decode_frame(raw, array, call, {"source": str(path)}, speed_of_sound_m_s=c)
    try:
        recs = P.load_recordings(args.real)
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None
    if not 0 <= args.index < len(recs):
        raise UsageError(f"--index {args.index}: {args.real} holds {len(recs)} recording(s)")
    return recs[args.index]


def _cmd_compare(args: argparse.Namespace) -> int:
    import json

    import processing as P
    from acousim.compare import ComparisonError, compare, summarize, write_comparison

    if (args.scene is None) == (args.sim is None):
        raise UsageError("give exactly one of --scene SCENE or --sim SIM")
    out = _writable_dir(args.out)
    methods = tuple(m.strip() for m in args.method.split(",") if m.strip())
    bad = [m for m in methods if m not in P.METHODS]
    if bad:
        raise UsageError(f"--method: unknown method(s) {bad}; choose from {list(P.METHODS)}")
    pairs = []
    if args.scene:
        from acousim.simulator import Simulator

        scene = _load_scene(args.scene)
        simulator = Simulator(scene)
        c = scene.environment.speed_of_sound_m_s
        n_real = _count_real(args)
        indices = range(n_real) if args.all else [args.index]
        for i in indices:
            args.index = i
            real = _load_real(args, c)
            pose = i if args.all else args.pose
            if not 0 <= pose < len(scene.sensor.poses):
                raise UsageError(f"--pose {pose}: the scene has {len(scene.sensor.poses)}")
            try:
                sim = simulator.simulate_pose(
                    scene.sensor.poses[pose], pose, n_samples=real.n_samples
                )
            except ValueError as exc:
                raise UsageError(str(exc)) from None
            pairs.append((real, sim))
    else:
        try:
            sims = P.load_recordings(args.sim)
        except P.RecordingFileError as exc:
            raise UsageError(f"--sim {args.sim}: {exc}") from None
        indices = range(min(len(sims), _count_real(args))) if args.all else [args.index]
        for i in indices:
            k = i if args.all else args.sim_index
            if not 0 <= k < len(sims):
                raise UsageError(f"--sim-index {k}: {args.sim} holds {len(sims)}")
            args.index = i
            pairs.append((_load_real(args, sims[k].speed_of_sound_m_s), sims[k]))
    reports = []
    for n, (real, sim) in enumerate(pairs):
        try:
            report, arrays = compare(real, sim, methods)
        except ComparisonError as exc:
            raise UsageError(f"pair {n}: {exc}") from None
        reports.append(report)
        folder = out if len(pairs) == 1 else out / f"pose_{n:04d}"
        files = write_comparison(report, arrays, folder)
    if len(pairs) > 1:
        table = summarize(reports)
        path = out / "summary.json"
        tmp = path.with_suffix(".json.part")
        tmp.write_text(json.dumps(table, indent=1))
        os.replace(tmp, path)
        s = table["summary"]
        print(
            f"{s['poses']} poses: mean envelope correlation "
            f"{s['mean_envelope_correlation']:.2f}, {s['matched_echoes']} matched echoes "
            f"(median |d_range| {s['median_abs_d_range_m']}, median |d_azimuth| "
            f"{s['median_abs_d_azimuth_deg']}); {path}"
        )
        return 0
    report = reports[0]
    al = report["alignment"]
    print(
        f"aligned by {al['emission_shift_samples']:.2f} samples, gain {al['gain']:.3g}; "
        f"mean envelope correlation {report['channels']['mean_envelope_correlation']:.2f}"
    )
    for m, r in report["images"].items():
        for k, p in enumerate(r["matched"]):
            print(
                f"  {m} echo {k}: real {p['real']['range_m']:.3f} m "
                f"{p['real']['azimuth_deg']:+.0f}°, sim {p['sim']['range_m']:.3f} m "
                f"{p['sim']['azimuth_deg']:+.0f}° (d_range {p['d_range_m'] * 100:+.1f} cm, "
                f"d_level {p['d_level_db']:+.1f} dB)"
            )
        print(
            f"  {m}: {len(r['only_real'])} echo(es) only in the real image, "
            f"{len(r['only_sim'])} only in the simulation"
        )
    for f in files:
        print(f"  {f}")
    return 0


def _count_real(args: argparse.Namespace) -> int:
    import processing as P

    if args.real == "rtisdev-sample" or args.real.endswith(".bin"):
        return 1
    try:
        return len(P.load_recordings(args.real))
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None


def _cmd_dataset(args: argparse.Namespace) -> int:
    from acousim.dataset import SpecError, generate

    _writable_dir(args.out)
    t0 = time.perf_counter()
    try:
        manifest = generate(
            args.spec,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            progress=_progress("shards"),
        )
    except (SpecError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    s = manifest["summary"]
    print(
        f"{manifest['samples']} samples in {len(manifest['shards'])} shards in {args.out} "
        f"({time.perf_counter() - t0:.1f} s; {s['samples_computed']} computed now, "
        f"{s['samples_per_second']:.2f} samples/s, {s['bytes_per_sample'] / 1e3:.0f} kB per "
        "sample)"
    )
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from acousim.experiments import StudyConfig, run_study
    from acousim.experiments.report import write_report

    _writable_dir(args.out)
    t0 = time.perf_counter()
    if args.report_only:
        from acousim.experiments.paper_study import load_results

        try:
            results = load_results(args.out)
        except (OSError, KeyError, ValueError) as exc:
            raise UsageError(f"--report-only: no finished study in {args.out!r} ({exc})") from None
        quick = results["config"].repetitions < 20
    else:
        quick = args.quick
        config = StudyConfig.quick(args.workers) if quick else StudyConfig(workers=args.workers)
        results = run_study(
            config, args.out, progress=lambda s: print(f"running {s} ...", flush=True)
        )
    command = "acousim reproduce" + (" --quick" if quick else "")
    report = write_report(results, args.report, args.out, command)
    print(f"figures and CSVs in {args.out}, report {report} ({time.perf_counter() - t0:.0f} s)")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    import processing as P

    try:
        recs = P.load_recordings(args.file)
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None
    print(f"{args.file}: {len(recs)} recording(s)")
    for i, r in enumerate(recs):
        kind = "simulated" if r.metadata.get("simulated") else "real"
        where = ""
        if "pose" in r.metadata:
            p = r.metadata["pose"]
            where = f", pose {[round(v, 3) for v in p['position_m']]} yaw {p['yaw_deg']:.1f}°"
        print(
            f"  [{i}] {kind}, array {r.array.name} ({r.array.n_mics} mics), "
            f"{r.n_measurements} measurement(s) x {r.n_samples} samples at "
            f"{r.sample_rate_hz / 1e3:g} kHz, call {r.waveform.kind} "
            f"{r.waveform.f_start_hz / 1e3:g}->{r.waveform.f_end_hz / 1e3:g} kHz, "
            f"c = {r.speed_of_sound_m_s:.1f} m/s{where}"
        )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="acousim",
        description="Simulate active in-air ultrasonic 3D sonars and image their recordings.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser(
        "demo",
        help="simulate the corridor drive and write its pictures",
        description="Simulate the bundled corridor drive (uRTIS at 10 Hz), "
        "image it with DAS, Capon-FBSS and MUSIC-FBSS, and write "
        "fan images, a 3D render and an animation.",
    )
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--seed", type=int, default=None, help="noise seed (default: the scene's)")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser(
        "simulate",
        help="simulate a scene file into an HDF5 recording file",
        description="Run a scene file for its pose or its whole trajectory "
        "and write every recording, with its ground truth, to one "
        "HDF5 file.",
    )
    p.add_argument("scene", help="scene file (.toml), see docs/scene-format.md")
    p.add_argument("--out", help="output file (default: SCENE_NAME.h5)")
    p.add_argument("--poses", help="pose indices: '0,3,5' or a range '0:10' (default: all)")
    p.add_argument("--seed", type=int, help="noise seed (default: the scene's)")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser(
        "image",
        help="image recordings and write pictures",
        description="Run the processing pipeline on simulated or real "
        "recordings and write fan images (azimuth x range), "
        "elevation-azimuth maps, a 3D render and, for a "
        "trajectory, an animated GIF.",
    )
    p.add_argument("file", help="recording file (.h5)")
    p.add_argument(
        "--method",
        default="das,capon-fbss,music-fbss",
        help="comma-separated methods: narrowband das, music[-fss|-fbss], "
        "capon[-fss|-fbss]; wideband capon[-fbss]-wb, music[-fbss]-wb; broadband das-bb, "
        "das-cf-bb, dmas2..5-bb, dmas2..5-cf-bb (default: das,capon-fbss,music-fbss)",
    )
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--index", help="recordings to image: '0,3' or '0:10' (default: all)")
    p.add_argument("--step", type=float, default=2.0, help="grid step in degrees (default: 2)")
    p.add_argument(
        "--energy-fraction",
        type=float,
        default=None,
        help="keep range bins with at least this fraction of the strongest "
        "bin's energy (default: 1e-3, ProcessingSettings'; the paper uses 0.5)",
    )
    p.add_argument(
        "--min-range",
        type=float,
        default=None,
        help="ignore nearer range bins, metres (default: 0.25, ProcessingSettings': "
        "the direct path)",
    )
    p.add_argument("--max-range", type=float, default=None, help="metres (default: all)")
    p.add_argument("--no-3d", action="store_true", help="skip the 3D render")
    p.add_argument("--no-animation", action="store_true", help="skip the animation")
    p.set_defaults(func=_cmd_image)

    p = sub.add_parser(
        "scenes",
        help="list the bundled scenes",
        description="List the bundled scene files and what each shows.",
    )
    p.set_defaults(func=_cmd_scenes)

    p = sub.add_parser(
        "info",
        help="describe what a recording file holds",
        description="Print what a recording file (HDF5) holds.",
    )
    p.add_argument("file", help="recording file (.h5)")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser(
        "record",
        help="record measurements from an RTIS sensor over USB",
        description="Record measurements from a real RTIS sensor (pyusb) or "
        "an emulated one, decode their PDM frames and write "
        "them to an HDF5 file. Ctrl-C keeps every complete "
        "measurement.",
    )
    p.add_argument("--device", help="USB VID:PID in hex (default: $RTIS_VID:$RTIS_PID)")
    p.add_argument("--serial", help="serial number of the sensor to use")
    p.add_argument("--count", type=int, help="number of measurements")
    p.add_argument("--duration", type=float, help="seconds of recording")
    p.add_argument(
        "--rate", type=float, default=10.0, help="measurements per second at most (default: 10)"
    )
    p.add_argument("--array", default="ertis_v3d1", help="array preset (default: ertis_v3d1)")
    p.add_argument("--call", default="default_25_50", help="RTIS call preset")
    p.add_argument(
        "--emulate",
        metavar="SCENE",
        help="record from an emulated sensor streaming this scene's simulation",
    )
    p.add_argument(
        "--filter",
        choices=PDM_FILTERS,
        default="equiripple",
        help="PDM decimation filter: equiripple (default, 157 taps, >80 dB alias "
        "rejection) or rtis (the vendor host's 512-tap FIR, 2-3x slower)",
    )
    p.add_argument("--out", required=True, help="output file (.h5)")
    p.set_defaults(func=_cmd_record)

    p = sub.add_parser(
        "compare",
        help="compare a real recording with its simulation",
        description="Put a real recording beside its simulation (from a "
        "scene and pose, or an existing simulated file): align "
        "the emission and the gain, compare matched-filter "
        "envelopes, range profiles and images, match their "
        "peaks, and write a JSON report and a picture.",
    )
    p.add_argument(
        "real",
        help="real recording: .h5, raw tick words (.bin), or "
        "'rtisdev-sample' (the eRTIS sample of the rtisdev wheel)",
    )
    p.add_argument("--index", type=int, default=0, help="recording in an .h5 file")
    p.add_argument("--scene", help="scene file to simulate at --pose")
    p.add_argument("--pose", type=int, default=0, help="pose index in the scene")
    p.add_argument("--sim", help="an existing simulated recording file (.h5)")
    p.add_argument("--sim-index", type=int, default=0, help="recording in the --sim file")
    p.add_argument(
        "--all",
        action="store_true",
        help="a trajectory: compare recording i with pose i (or --sim recording i)"
        " for every i; one row per pose and a summary in summary.json",
    )
    p.add_argument(
        "--array", default="ertis_v3d1", help="array of a raw .bin (default: ertis_v3d1)"
    )
    p.add_argument("--call", default="default_25_50", help="call of a raw .bin")
    p.add_argument(
        "--method", default="das", help="comma-separated methods (as for image; e.g. das,das-bb)"
    )
    p.add_argument("--out", default="out/compare", help="output folder")
    p.set_defaults(func=_cmd_compare)

    p = sub.add_parser(
        "dataset",
        help="generate a dataset of simulated measurements",
        description="Generate a sharded, reproducible, resumable dataset "
        "from a spec file (docs/dataset-format.md), on local "
        "processes or a Dask cluster. Run it again to resume.",
    )
    p.add_argument("spec", help="dataset spec (.toml)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--workers", type=int, default=2, help="local processes (default: 2)")
    p.add_argument("--scheduler", help="address of a Dask scheduler (instead of --workers)")
    p.set_defaults(func=_cmd_dataset)

    p = sub.add_parser(
        "reproduce",
        help="reproduce the paper's simulation study",
        description="Run the paper's section IV experiments (Figs. 3-12), "
        "write a CSV and a PNG per figure and regenerate the "
        "report that puts the paper's numbers beside ours.",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="3 repetitions, few SNRs/snapshots, 0.5 degree grid (about a minute)",
    )
    p.add_argument("--out", default="docs/reproduction", help="folder for figures and CSVs")
    p.add_argument("--report", default="docs/REPRODUCTION.md", help="report to (re)write")
    p.add_argument("--workers", type=int, default=2, help="processes (default: 2)")
    p.add_argument(
        "--report-only",
        action="store_true",
        help="rewrite the report from the CSVs of a finished run in --out",
    )
    p.set_defaults(func=_cmd_reproduce)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except UsageError as exc:
        print(f"acousim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"acousim {args.command}: interrupted; no partial file was kept", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
