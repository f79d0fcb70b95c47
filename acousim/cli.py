"""The ``acousim`` command line: a thin layer that parses, calls the library, reports.

Errors in what the user gave (a file, a key, a value) are
:class:`processing.errors.InputError`, caught once in :func:`main` and reported on one
line with exit code 2; every other exception is a bug and keeps its traceback.
Numeric arguments are checked when parsed, by the same declarations
(:mod:`processing.settings`) as the files. Files are written under a temporary name
and renamed when complete, so an error or Ctrl-C leaves no partial output.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import signal
import sys
import time
from pathlib import Path

from processing.errors import InputError

# hardware.pdm.FILTERS, repeated so that the parser does not import scipy.signal (tested)
PDM_FILTERS = ("equiripple", "rtis")
# processing.PRESETS and the RTIS call presets, repeated for the same reason (tested)
ARRAY_PRESETS = ("ertis_v3d1", "paper_8x8", "urtis_v1")
CALL_PRESETS = ("default_20_80", "default_25_50")


def _headless_vtk() -> None:
    """Pictures are rendered off screen: without a display on Linux, let VTK start with
    its EGL window instead of trying X first and warning "bad X server connection" on
    every run (same pixels).  A VTK_DEFAULT_OPENGL_WINDOW the user set is kept."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


_headless_vtk()  # before any command imports VTK


class UsageError(InputError):
    """Bad input on the command line: printed on one line by main(), exit code 2."""


def _checked(kind: str, lo: float = -math.inf, hi: float = math.inf, *, declared=None):
    """An argparse type: the text as a number checked by a setting declaration
    (`declared()` returns a :class:`processing.settings.Setting`, imported lazily so
    that building the parser stays light), else a range given here."""

    def parse(text: str):
        from processing.settings import Setting, check

        decl = declared() if declared else Setting(kind, lo=lo, hi=hi)
        try:
            value = int(text) if decl.kind == "int" else float(text)
        except ValueError:
            what = "a whole number" if decl.kind == "int" else "a number"
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        try:
            return check(decl, value, "")
        except InputError as exc:
            raise argparse.ArgumentTypeError(f"{text!r}: {exc.reason}") from None

    parse.__name__ = kind
    return parse


def _declared(module: str, cls: str, name: str):
    def get():
        import importlib

        from processing.settings import settings_of

        return settings_of(getattr(importlib.import_module(module), cls))[name]

    return get


SEED = _checked("int", declared=_declared("acousim.scene.model", "Simulation", "seed"))
INDEX = _checked("int", 0, 2**31 - 1)
WORKERS = _checked("int", 1, 1024)


def _methods(option: str, text: str) -> tuple[str, ...]:
    """Comma-separated DOA methods, each checked by :func:`processing.check_method`."""
    import processing as P

    methods = tuple(m.strip() for m in text.split(",") if m.strip())
    if not methods:
        raise UsageError("no method given", key=option, value=text)
    try:
        return tuple(P.check_method(m) for m in methods)
    except InputError as exc:
        raise UsageError(f"{exc.value!r}: {exc.reason}", key=option, value=text) from None


def _output_file(option: str, path: str | Path) -> Path:
    """An output file path: not an existing folder, its folder writable."""
    out = Path(path)
    if out.is_dir():
        raise UsageError("is a folder; give a file name", key=option, value=str(path))
    _writable_dir(out.parent)
    return out


def bundled_scenes() -> Path:
    """The bundled scenes' folder (installed package data, or the source tree's)."""
    from acousim.bundled import data_dir

    return data_dir("scenes")


def _progress(desc: str):
    """A tqdm progress callback: shown after a second, and only on a terminal."""
    from tqdm import tqdm

    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        _stop_if_interrupted()
        if bar is None:
            bar = tqdm(
                total=total, desc=desc, delay=1.0, disable=not sys.stderr.isatty(), leave=False
            )
        bar.update(done - bar.n)
        if done == total:
            bar.close()

    return update


_interrupted = False


def _on_interrupt(signum, frame) -> None:
    """SIGINT: remember it, then raise KeyboardInterrupt as Python does. Some optional
    imports (trimesh's) catch BaseException and would swallow it; the flag makes
    :func:`_stop_if_interrupted` raise it again at the next checkpoint."""
    global _interrupted
    _interrupted = True
    raise KeyboardInterrupt


def _stop_if_interrupted() -> None:
    """A checkpoint: raise KeyboardInterrupt if Ctrl-C came, even if it was swallowed."""
    if _interrupted:
        raise KeyboardInterrupt


def _preload_simulation() -> None:
    """Import what a simulation needs before its work starts, with Ctrl-C held back
    until the imports are done (trimesh tries optional imports that catch
    BaseException: an interrupt there broke its import with a TypeError), then honour
    an interrupt that came meanwhile."""
    import signal

    held = hasattr(signal, "pthread_sigmask")
    if held:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        import trimesh  # noqa: F401

        import acousim.simulator  # noqa: F401
    finally:
        if held:  # a Ctrl-C that came meanwhile is delivered now
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    _stop_if_interrupted()


def _writable_dir(path: str | Path) -> Path:
    import tempfile

    from processing.atomic import TEMP_PREFIX

    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=TEMP_PREFIX):  # exclusive, removed
            pass
    except OSError as exc:
        raise UsageError(
            f"output directory {str(out)!r} cannot be written ({exc.strerror})"
        ) from None
    return out


def _load_scene(path: str | Path):
    from acousim.bundled import resolve_scene
    from acousim.scene import load_scene

    return load_scene(resolve_scene(path))  # a file, or a bundled scene's name


def _parse_indices(option: str, text: str | None) -> list[int] | None:
    """Indices '0,3,5' or ranges '0:10' (end excluded); None when not given."""
    if text is None:
        return None
    out: list[int] = []
    expected = "expected indices like '0,3,5' or a range '0:10'"
    for part in text.split(","):
        a, colon, b = part.partition(":")
        try:
            lo = int(a)
            hi = int(b) if colon else lo + 1
        except ValueError:
            raise UsageError(expected, key=option, value=text) from None
        if lo < 0 or hi <= lo:
            raise UsageError(
                f"{part!r} selects nothing or a negative index; {expected}", key=option, value=text
            )
        out.extend(range(lo, hi))
    return out


def _simulate(scene, poses, seed):
    from acousim.simulator import Simulator

    if seed is not None:
        scene = dataclasses.replace(
            scene, simulation=dataclasses.replace(scene.simulation, seed=seed)
        )
    recs = Simulator(scene).run(poses, progress=_progress("simulate"))
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

    poses = _parse_indices("--poses", args.poses)
    scene = _load_scene(args.scene)
    out = _output_file("--out", args.out or f"{scene.name}.h5")
    _preload_simulation()
    t0 = time.perf_counter()
    recs = _simulate(scene, poses, args.seed)
    _stop_if_interrupted()
    P.save_recordings(out, recs)
    print(
        f"{len(recs)} recording(s) of {scene.name!r} written to {out} "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return 0


def _load_and_image(args: argparse.Namespace):
    """`image` and `export`: the options, the recordings of --index and their indices
    in the file, and a function that images them (called once the command is ready)."""
    import processing as P
    from acousim.imaging import ImagingOptions, image_recordings

    given = {"energy_fraction": args.energy_fraction, "min_range_m": args.min_range}
    options = ImagingOptions(  # unset options keep ProcessingSettings' defaults
        methods=_methods("--method", args.method),
        step_deg=args.step,
        max_range_m=args.max_range,
        peak_threshold_db=args.peak_threshold,
        **{k: v for k, v in given.items() if v is not None},
    )
    if options.max_range_m is not None and options.max_range_m <= options.min_range_m:
        raise UsageError(
            f"must be above --min-range {options.min_range_m:g}",
            key="--max-range",
            value=args.max_range,
        )
    index = _parse_indices("--index", args.index)
    try:
        n = P.count_recordings(args.file)
        if n == 0:
            raise UsageError(f"{args.file}: the file holds no recordings")
        if index is not None:
            bad = [i for i in index if not 0 <= i < n]
            if bad:
                raise UsageError(f"the file holds {n} recording(s)", key="--index", value=bad)
        index = list(range(n)) if index is None else index
        recs = [P.load_recording(args.file, i) for i in index]  # only those asked for
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None
    return recs, index, options, lambda: _image_all(recs, options, image_recordings)


def _image_all(recs, options, image_recordings):
    return image_recordings(recs, options, _progress("image"))


def _cmd_image(args: argparse.Namespace) -> int:
    from acousim.export import write_image_data, write_peaks_csv
    from acousim.imaging import prepare_pictures, write_pictures

    out = _writable_dir(args.out)
    recs, index, options, run = _load_and_image(args)
    animation = not args.no_animation and len(recs) > 1
    prepare_pictures(render_3d=not args.no_3d, animation=animation)  # before the work
    images = run()
    files = []
    if not args.no_data:
        files += [
            write_image_data(out / "images.h5", recs, images, index),
            write_peaks_csv(
                out / "peaks.csv", recs, images, index, threshold_db=args.peak_threshold
            ),
        ]
    files += write_pictures(
        recs,
        images,
        out,
        options,
        render_3d=not args.no_3d,
        animation=animation,
        progress=_progress("animate"),
        indices=index,
    )
    for f in files:
        print(f"  {f}")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.exists():
        raise UsageError(f"--out {str(out)!r} exists already; a bag is never overwritten")
    _writable_dir(out.parent)
    try:
        from acousim.export.rosbag import write_rosbag
    except ImportError as exc:
        raise UsageError(str(exc)) from None
    recs, index, options, run = _load_and_image(args)
    if args.image_method and args.image_method not in options.methods:
        raise UsageError(
            f"--image-method {args.image_method!r} is not among --method {args.method!r}"
        )
    images = run()
    write_rosbag(
        out,
        recs,
        images,
        index,
        method=args.image_method,
        threshold_db=args.peak_threshold,
    )
    print(f"{len(recs)} recording(s) written to the ROS 2 bag {out} (MCAP)")
    return 0


def _imaging_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `image` and `export`."""
    p.add_argument("file", help="recording file (.h5)")
    p.add_argument(
        "--method",
        default="das,capon-fbss,music-fbss",
        help="comma-separated methods: narrowband das, music[-fss|-fbss], "
        "capon[-fss|-fbss]; wideband capon[-fbss]-wb, music[-fbss]-wb; broadband das-bb, "
        "das-cf-bb, dmas2..5-bb, dmas2..5-cf-bb (default: das,capon-fbss,music-fbss)",
    )
    p.add_argument("--index", help="recordings to image: '0,3' or '0:10' (default: all)")
    p.add_argument(
        "--step",
        type=_checked(
            "float", declared=_declared("acousim.dataset.spec", "StoreOptions", "step_deg")
        ),
        default=2.0,
        help="grid step in degrees, 0.1 to 45 (default: 2)",
    )
    p.add_argument(
        "--energy-fraction",
        type=_checked("float", 0, 1),
        default=None,
        help="keep range bins with at least this fraction of the strongest "
        "bin's energy (default: 1e-3, ProcessingSettings'; the paper uses 0.5)",
    )
    p.add_argument(
        "--min-range",
        type=_checked("float", 0, 1000),
        default=None,
        help="ignore nearer range bins, metres (default: 0.25, ProcessingSettings': "
        "the direct path)",
    )
    p.add_argument(
        "--max-range",
        type=_checked("float", 0.01, 1000),
        default=None,
        help="metres (default: all)",
    )
    p.add_argument(
        "--peak-threshold",
        type=float,
        default=-10.0,
        help="peaks kept within this many dB of each image's strongest cell (default: -10)",
    )


def _cmd_scenes(args: argparse.Namespace) -> int:
    from acousim.bundled import scene_files
    from acousim.scene import SceneError, load_scene
    from processing.errors import InputError

    for f in scene_files():
        try:
            sc = load_scene(f)
        except (SceneError, InputError) as exc:
            print(f"{f.name:18s} invalid ({exc})")
            continue
        except (OSError, RuntimeError) as exc:  # e.g. a layout that cannot be fetched
            print(f"{f.name:18s} unavailable here ({exc})")
            continue
        print(
            f"{f.name:18s} {sc.sensor.array.name}, {len(sc.sensor.poses)} pose(s): {sc.description}"
        )
    if args.verbose:
        print(f"(in {bundled_scenes()}; `acousim simulate wall` runs wall.toml)")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    import processing as P
    from acousim.imaging import ImagingOptions, image_recordings, write_pictures

    t0 = time.perf_counter()
    out = _writable_dir(args.out)
    scene = _load_scene(bundled_scenes() / "corridor.toml")
    _preload_simulation()
    recs = _simulate(scene, None, args.seed)
    _stop_if_interrupted()
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


def _emulation_recordings(scene, count: int | None) -> list:
    """The recordings an emulated sensor streams: the scene's first poses (at most
    `count`, else 10), simulated at the sensor's 450 kHz."""
    from acousim.simulator import Simulator

    if scene.sensor.sample_rate_hz != 450e3:
        raise UsageError(
            f"--emulate {scene.source}: the scene samples at "
            f"{scene.sensor.sample_rate_hz:g} Hz; the sensor at 450000"
        )
    n = min(len(scene.sensor.poses), count or 10)
    try:
        sim = Simulator(scene)
        return [sim.simulate_pose(scene.sensor.poses[i], i) for i in range(n)]
    except InputError as exc:  # an unreadable mesh, a scene the simulator refuses
        raise UsageError(f"--emulate {scene.source}: {exc}") from None


def _cmd_record(args: argparse.Namespace) -> int:
    import processing as P
    from hardware import (
        DeviceNotFound,
        DeviceSettings,
        Recorder,
        RecordingFailed,
        RecordingInterrupted,
        check_acquisition,
    )
    from hardware.device import RtisDevice, find_ids, parse_usb_id
    from hardware.emulator import emulated_device
    from processing.errors import InputError

    try:
        check_acquisition(args.count, args.duration, args.rate)
        out = _output_file("--out", args.out)
        if args.emulate:
            scene = _load_scene(args.emulate)
            _preload_simulation()
            array, call = scene.sensor.array, scene.sensor.call
            recs = _emulation_recordings(scene, args.count)
            try:
                open_device, _ = emulated_device(recs, array.channels, serial=args.serial)
            except InputError as exc:
                raise UsageError(
                    f"--emulate {args.emulate}: array {array.name!r}: {exc.reason}"
                ) from None
        else:
            vid, pid = parse_usb_id(args.device) if args.device else find_ids()
            array, call = P.preset(args.array), P.rtis_call(args.call)

            def open_device():
                return RtisDevice(vid, pid, serial=args.serial)

        recorder = Recorder(
            open_device, DeviceSettings(call=call.sampled(450e3)), array, call, fir=args.filter
        )
    except (InputError, DeviceNotFound) as exc:
        raise UsageError(str(exc)) from None
    except RecordingFailed as exc:
        print(f"acousim record: error: {exc.reason}; nothing recorded", file=sys.stderr)
        return 1
    bar = _progress("record")
    kept: list = []

    def keep(rec) -> None:
        kept.append(rec)
        if args.count:
            bar(len(kept), args.count)

    interrupted, failure = False, None
    try:
        recorder.acquire(args.count, args.duration, args.rate, on_record=keep)
    except RecordingInterrupted:
        interrupted = True
    except RecordingFailed as exc:
        failure = exc
    if kept:
        P.save_recordings(out, kept)
    st = recorder.stats
    print(
        (f"{len(kept)} measurement(s) written to {out}" if kept else "no measurement taken")
        + (" (interrupted)" if interrupted else "")
        + (" (the sensor failed)" if failure else "")
        + f"; lost {len(st.lost_indices)}"
        + (f" (indices {st.lost_indices[:10]})" if st.lost_indices else "")
        + f", corrupt {st.corrupt}, time-outs {st.timeouts}, reconnects {st.reconnects}"
        + (f", counter resets {len(st.counter_resets)}" if st.counter_resets else "")
    )
    if failure:
        print(f"acousim record: error: {failure}", file=sys.stderr)
        return 1
    return 130 if interrupted else 0


def _cmd_compare(args: argparse.Namespace) -> int:
    import processing as P
    from acousim.compare import (
        compare,
        load_real_recordings,
        pair_with_file,
        pair_with_scene,
        summarize,
        write_comparison,
        write_summary,
    )
    from processing.errors import InputError

    if (args.scene is None) == (args.sim is None):
        raise UsageError("give exactly one of --scene SCENE or --sim SIM")
    out = _writable_dir(args.out)
    methods = _methods("--method", args.method)
    try:
        if args.scene:
            scene = _load_scene(args.scene)
            c = scene.environment.speed_of_sound_m_s
        else:
            try:
                sims = P.load_recordings(args.sim)
            except P.RecordingFileError as exc:
                raise UsageError(f"--sim {args.sim}: {exc}") from None
            if not sims:
                raise UsageError(f"--sim {args.sim}: the file holds no recording")
            c = sims[0].speed_of_sound_m_s
        reals = load_real_recordings(
            args.real, array=args.array, call=args.call, speed_of_sound_m_s=c
        )
        if args.scene:
            pairs = pair_with_scene(reals, scene, every=args.all, index=args.index, pose=args.pose)
        else:
            pairs = pair_with_file(
                reals, sims, every=args.all, index=args.index, sim_index=args.sim_index
            )
        reports = []
        for n, (real, sim) in enumerate(pairs):
            try:
                report, arrays = compare(real, sim, methods)
            except InputError as exc:
                raise UsageError(f"pair {n}: {exc}") from None
            reports.append(report)
            folder = out if len(pairs) == 1 else out / f"pose_{n:04d}"
            files = write_comparison(report, arrays, folder)
    except InputError as exc:
        raise UsageError(str(exc)) from None
    if len(reports) > 1:
        s = summarize(reports)
        path = write_summary(s, out)
        print(
            f"{s.poses} poses: mean envelope correlation {s.mean_envelope_correlation:.2f}, "
            f"{s.matched_echoes} matched echoes (median |d_range| {s.median_abs_d_range_m}, "
            f"median |d_azimuth| {s.median_abs_d_azimuth_deg}); {path}"
        )
        return 0
    report = reports[0]
    al = report.alignment
    print(
        f"aligned by {al.emission_shift_samples:.2f} samples, gain {al.gain:.3g}; "
        f"mean envelope correlation {report.mean_envelope_correlation:.2f}"
    )
    for m, r in report.images.items():
        for k, p in enumerate(r.matched):
            print(
                f"  {m} echo {k}: real {p.real.range_m:.3f} m {p.real.azimuth_deg:+.0f}°, "
                f"sim {p.sim.range_m:.3f} m {p.sim.azimuth_deg:+.0f}° "
                f"(d_range {p.d_range_m * 100:+.1f} cm, d_level {p.d_level_db:+.1f} dB)"
            )
        print(
            f"  {m}: {len(r.side_lobes_real)} side lobe(s) in the real image, "
            f"{len(r.side_lobes_sim)} in the simulation; {len(r.only_real)} echo(es) only "
            f"in the real image, {len(r.only_sim)} only in the simulation"
        )
    for f in files:
        print(f"  {f}")
    return 0


def _cmd_dataset(args: argparse.Namespace) -> int:
    from acousim.dataset import generate

    if args.scheduler:
        from acousim.dataset.safety import check_scheduler

        check_scheduler(args.scheduler)
    _writable_dir(args.out)
    _preload_simulation()
    t0 = time.perf_counter()
    from acousim.bundled import resolve

    manifest = generate(
        resolve("datasets", args.spec),  # a file, or a bundled spec's name
        args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=_progress("shards"),
    )
    s = manifest["summary"]
    print(
        f"{manifest['samples']} samples in {len(manifest['shards'])} shards in {args.out} "
        f"({time.perf_counter() - t0:.1f} s; {s['samples_computed']} computed now, "
        f"{s['samples_per_second']:.2f} samples/s, {s['bytes_per_sample'] / 1e3:.0f} kB per "
        "sample)"
    )
    return 0


def _refuse_to_overwrite_a_full_run(out: Path, report: Path) -> None:
    """A --quick run does not replace the figures, CSVs or report of a full run."""
    import json

    try:
        meta = json.loads((out / "study.json").read_text())
        full_figures = int(meta["config"]["repetitions"]) >= 20
    except (OSError, ValueError, KeyError, TypeError):
        full_figures = False
    full_report = (
        report.is_file()
        and "Generated by `acousim reproduce` on" in (report.read_text(errors="replace")[:400])
    )
    if full_figures or full_report:
        what = f"--out {out}" if full_figures else f"--report {report}"
        raise UsageError(
            f"{what}: holds the results of a full run; a --quick run does not overwrite "
            "them (choose another --out/--report, or give --overwrite)"
        )


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from acousim.experiments import StudyConfig, run_study
    from acousim.experiments.report import write_report

    _writable_dir(args.out)
    report_path = Path(args.report) if args.report else Path(args.out) / "REPRODUCTION.md"
    quick = args.quick
    if not args.report_only and quick and not args.overwrite:
        _refuse_to_overwrite_a_full_run(Path(args.out), report_path)
    t0 = time.perf_counter()
    if args.report_only:
        from acousim.experiments.paper_study import load_results

        try:
            results = load_results(args.out)
        except InputError as exc:
            raise UsageError(f"--report-only: no finished study in {args.out!r} ({exc})") from None
        quick = results.config.repetitions < 20
    else:
        config = StudyConfig.quick(args.workers) if quick else StudyConfig(workers=args.workers)
        results = run_study(
            config, args.out, progress=lambda s: print(f"running {s} ...", flush=True)
        )
    command = "acousim reproduce" + (" --quick" if quick else "")
    report = write_report(results, report_path, args.out, command)
    print(f"figures and CSVs in {args.out}, report {report} ({time.perf_counter() - t0:.0f} s)")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from acousim.dataset.info import describe

    for line in describe(args.file):  # an InputError is reported by main()
        print(line)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="acousim",
        description="Simulate active in-air ultrasonic 3D sonars and image their recordings.",
    )
    from acousim.bundled import version

    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser(
        "demo",
        help="simulate the corridor drive and write its pictures",
        description="Simulate the bundled corridor drive (uRTIS at 10 Hz), "
        "image it with DAS, Capon-FBSS and MUSIC-FBSS, and write "
        "fan images, a 3D render and an animation.",
    )
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--seed", type=SEED, default=None, help="noise seed (default: the scene's)")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser(
        "simulate",
        help="simulate a scene file into an HDF5 recording file",
        description="Run a scene file for its pose or its whole trajectory "
        "and write every recording, with its ground truth, to one "
        "HDF5 file.",
    )
    p.add_argument(
        "scene",
        help="scene file (.toml, see docs/scene-format.md) or a bundled scene's name "
        "(acousim scenes)",
    )
    p.add_argument("--out", help="output file (default: SCENE_NAME.h5)")
    p.add_argument("--poses", help="pose indices: '0,3,5' or a range '0:10' (default: all)")
    p.add_argument("--seed", type=SEED, help="noise seed (default: the scene's)")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser(
        "image",
        help="image recordings and write pictures and data files",
        description="Run the processing pipeline on simulated or real "
        "recordings and write the images as data (images.h5: range x "
        "elevation x azimuth in dB with its axes; peaks.csv), fan images "
        "(azimuth x range), elevation-azimuth maps, a 3D render and, for a "
        "trajectory, an animated GIF. File layouts: docs/export.md.",
    )
    _imaging_arguments(p)
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--no-3d", action="store_true", help="skip the 3D render")
    p.add_argument("--no-animation", action="store_true", help="skip the animation")
    p.add_argument(
        "--no-data",
        action="store_true",
        help="skip images.h5 and peaks.csv (about 2 MB per image of a corridor pose)",
    )
    p.set_defaults(func=_cmd_image)

    p = sub.add_parser(
        "export",
        help="write recordings and their images to a ROS 2 bag (MCAP)",
        description="Image recordings and write a rosbag2 folder (MCAP storage) "
        "with the raw samples (std_msgs/Float32MultiArray), the image peaks "
        "(sensor_msgs/PointCloud2), the fan image (sensor_msgs/Image), the sensor "
        "pose (/tf) and the sensor's description (std_msgs/String, JSON). Needs "
        "the rosbags package (pip install 'acousim[ros]'); no ROS installation. "
        "Layout: docs/export.md.",
    )
    _imaging_arguments(p)
    p.add_argument("--out", required=True, help="bag folder to create (must not exist)")
    p.add_argument(
        "--image-method",
        default=None,
        help="the method published as peaks and fan (default: the sharpest imaged)",
    )
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser(
        "scenes",
        help="list the bundled scenes",
        description="List the bundled scenes and what each shows; `acousim simulate "
        "NAME` runs one by its name.",
    )
    p.add_argument("-v", "--verbose", action="store_true", help="also say where they are")
    p.set_defaults(func=_cmd_scenes)

    p = sub.add_parser(
        "info",
        help="describe a recording file, a dataset shard or a dataset folder",
        description="Print what a recording file (HDF5), a dataset shard (.h5) or a "
        "dataset folder (with its manifest.json) holds.",
    )
    p.add_argument("file", help="recording file, dataset shard or dataset folder")
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
    p.add_argument("--count", type=_checked("int", 1, 10**9), help="number of measurements")
    p.add_argument("--duration", type=_checked("float", 1e-3, 1e7), help="seconds of recording")
    p.add_argument(
        "--rate",
        type=_checked("float", 1e-3, 1e4),
        default=10.0,
        help="measurements per second at most (default: 10)",
    )
    p.add_argument(
        "--array",
        default="ertis_v3d1",
        choices=ARRAY_PRESETS,
        help="array preset (default: ertis_v3d1)",
    )
    p.add_argument("--call", default="default_25_50", choices=CALL_PRESETS, help="RTIS call preset")
    p.add_argument(
        "--emulate",
        metavar="SCENE",
        help="record from an emulated sensor streaming this scene's simulation (a scene "
        "file or a bundled scene's name)",
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
        "peaks (a weaker peak within one STFT window of a stronger "
        "one is reported as its side lobe), and write a JSON report "
        "and a picture (docs/compare.md).",
    )
    p.add_argument(
        "real",
        help="real recording: .h5, raw tick words (.bin), or "
        "'rtisdev-sample' (the eRTIS sample of the rtisdev wheel)",
    )
    p.add_argument("--index", type=INDEX, default=0, help="recording in an .h5 file")
    p.add_argument("--scene", help="scene file (or a bundled scene's name) to simulate at --pose")
    p.add_argument("--pose", type=INDEX, default=0, help="pose index in the scene")
    p.add_argument("--sim", help="an existing simulated recording file (.h5)")
    p.add_argument("--sim-index", type=INDEX, default=0, help="recording in the --sim file")
    p.add_argument(
        "--all",
        action="store_true",
        help="a trajectory: compare recording i with pose i (or --sim recording i)"
        " for every i; one row per pose and a summary in summary.json",
    )
    p.add_argument(
        "--array",
        default="ertis_v3d1",
        choices=ARRAY_PRESETS,
        help="array of a raw .bin (default: ertis_v3d1)",
    )
    p.add_argument(
        "--call", default="default_25_50", choices=CALL_PRESETS, help="call of a raw .bin"
    )
    p.add_argument(
        "--method", default="das", help="comma-separated methods (as for image; e.g. das,das-bb)"
    )
    p.add_argument("--out", default="out/compare", help="output folder (default: out/compare)")
    p.set_defaults(func=_cmd_compare)

    p = sub.add_parser(
        "dataset",
        help="generate a dataset of simulated measurements",
        description="Generate a sharded, reproducible, resumable dataset "
        "from a spec file (docs/dataset-format.md), on local "
        "processes or a Dask cluster. Run it again to resume.",
    )
    p.add_argument(
        "spec", help="dataset spec (.toml) or a bundled spec's name (e.g. corridor_small)"
    )
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--workers", type=WORKERS, default=2, help="local processes (default: 2)")
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
    p.add_argument(
        "--out",
        default="reproduction",
        help="folder for figures and CSVs (default: %(default)s, in the current folder; "
        "the committed ones are docs/reproduction)",
    )
    p.add_argument(
        "--report",
        help="report to (re)write (default: OUT/REPRODUCTION.md; the committed one is "
        "docs/REPRODUCTION.md, written with --out docs/reproduction)",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="let a --quick run overwrite the report of a full run",
    )
    p.add_argument("--workers", type=WORKERS, default=2, help="processes (default: 2)")
    p.add_argument(
        "--report-only",
        action="store_true",
        help="rewrite the report from the CSVs of a finished run in --out",
    )
    p.set_defaults(func=_cmd_reproduce)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse, run one command; an InputError is one line on stderr and exit code 2,
    Ctrl-C exit code 130, anything else a bug with its traceback."""
    global _interrupted
    parser = build_parser()
    args = parser.parse_args(argv)
    _interrupted = False
    import threading

    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGINT, _on_interrupt)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"acousim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"acousim {args.command}: interrupted; no partial file was kept", file=sys.stderr)
        return 130
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


if __name__ == "__main__":
    sys.exit(main())
