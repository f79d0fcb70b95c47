"""``acousim image``: image recordings and write pictures and data files.

Run the processing pipeline on simulated or real recordings and write the images as data
(images.h5: range x elevation x azimuth in dB with its axes; peaks.csv), fan images
(azimuth x range), elevation-azimuth maps, a 3D render and, for a trajectory, an
animated GIF. File layouts: docs/export.md.
"""

from __future__ import annotations

import argparse
import contextlib
import functools

from acousim.cli.common import (
    UsageError,
    add_command,
    choice,
    elapsed,
    methods,
    parse_indices,
    progress,
    writable_dir,
)
from acousim.cli.options import add_declared

IMAGING = "acousim.imaging.run:ImagingOptions"


def imaging_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `image` and `export`."""
    p.add_argument("file", help="recording file (.h5: ours, or a CHIRP file)")
    p.add_argument(
        "--method",
        default=None,  # ImagingOptions.methods (spelt out in the help; a test holds it)
        help="comma-separated methods: narrowband das, music[-fss|-fbss], "
        "capon[-fss|-fbss]; wideband capon[-fbss]-wb, music[-fbss]-wb; broadband das-bb, "
        "das-cf-bb, dmas2..5-bb, dmas2..5-cf-bb (default: das,capon-fbss,music-fbss)",
    )
    p.add_argument("--index", help="recordings to image: '0,3' or '0:10' (default: all)")
    p.add_argument(
        "--sensor",
        metavar="NAME",
        help="a rig's recordings: only those of the sonar NAME (of --index, if given)",
    )
    add_declared(p, "--step", IMAGING, "step_deg")
    add_declared(p, "--energy-fraction", IMAGING, "energy_fraction")
    add_declared(p, "--min-range", IMAGING, "min_range_m", note="the direct path lies nearer")
    add_declared(p, "--max-range", IMAGING, "max_range_m", note="default: all")
    add_declared(p, "--peak-threshold", IMAGING, "peak_threshold_db")
    add_declared(p, "--dynamic-range-db", IMAGING, "dynamic_range_db", note="every picture")
    p.add_argument(
        "--call",
        type=choice("call", CHIRP_CALLS),
        help="the emitted call of a CHIRP file that does not say it (no transmitter "
        "signal, or one that is not a sweep): an RTIS preset or 'paper' (ignored otherwise)",
    )


#: calls a CHIRP file may be read with (--call): :data:`processing.CALLS`, spelt out
#: here so that building the parser imports no numpy (a test holds them equal)
CHIRP_CALLS = ("default_20_80", "default_25_50", "paper")


def _of_sensor(recs: list, index: list[int], name: str) -> tuple[list, list[int]]:
    """The recordings (and their indices) of the rig's sonar `name`; a UsageError
    naming the sonars there are when none is."""
    names = [r.metadata.get("sensor") for r in recs]
    keep = [i for i, n in enumerate(names) if n == name]
    if not keep:
        there = sorted({n for n in names if n is not None})
        raise UsageError(
            f"no recording of sonar {name!r}"
            + (f"; the file's sonars: {', '.join(there)}" if there else " (not a rig's file)"),
            key="--sensor",
            value=name,
        )
    return [recs[i] for i in keep], [index[i] for i in keep]


def call_waveform(name: str | None):
    """The Waveform of a --call name (None: None), as a scene file's call."""
    import processing as P

    return None if name is None else P.named_call(name)


def load_and_image(args: argparse.Namespace):
    """`image` and `export`: the options, the recordings of --index and their indices
    in the file, and a function that images them (called once the command is ready)."""
    import processing as P
    from acousim.allocator import small_pages
    from acousim.cli.ahead import shared_by_two_processes
    from acousim.imaging.run import ImagingOptions, image_recordings, recording_images
    from acousim.process import configure

    # the process's policy, as a simulating command's: BLAS on one thread (the same
    # bytes on every host), freed memory kept for reuse (the label maps' and the
    # pictures' arrays of tens of MB: half the page faults' time); and those arrays
    # on small pages (a huge page's fault cost more system time than it saved)
    configure()
    small_pages()
    given = {
        "step_deg": args.step,
        "energy_fraction": args.energy_fraction,
        "min_range_m": args.min_range,
        "max_range_m": args.max_range,
        "peak_threshold_db": args.peak_threshold,
        "dynamic_range_db": args.dynamic_range_db,
    }
    if args.method is not None:
        given["methods"] = methods("--method", args.method)
    options = ImagingOptions(  # unset options keep their declared defaults
        **{k: v for k, v in given.items() if v is not None},
    )
    if options.max_range_m is not None and options.max_range_m <= options.min_range_m:
        raise UsageError(
            f"must be above --min-range {options.min_range_m:g}",
            key="--max-range",
            value=args.max_range,
        )
    index = parse_indices("--index", args.index)
    try:
        n = P.count_recordings(args.file)
        if n == 0:
            raise UsageError(f"{args.file}: the file holds no recordings")
        if index is not None:
            bad = [i for i in index if not 0 <= i < n]
            if bad:
                raise UsageError(f"the file holds {n} recording(s)", key="--index", value=bad)
        index = list(range(n)) if index is None else index
        call = call_waveform(args.call)
        recs = [P.load_recording(args.file, i, call=call) for i in index]  # only those asked
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None
    if getattr(args, "sensor", None) is not None:
        recs, index = _of_sensor(recs, index, args.sensor)

    def image_all(each=None):  # the bar's time starts with the work
        bar = progress("image", "recording")
        # the odd recordings imaged in a forked process, the even ones here
        made = shared_by_two_processes(lambda k: recording_images(recs[k], options, k), len(recs))
        with contextlib.closing(made):
            return image_recordings(recs, options, bar, each=each, made=made)

    return recs, index, options, image_all


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    imaging_arguments(p)
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument(
        "--recording",
        help="the recording(s) the fan, el-az and 3D pictures show, by index in the file: "
        "'2', '0,5' or a range '2:5' (end excluded); among those imaged (default: the "
        "first imaged); several write fan_N.png, elaz_METHOD_N.png, scene3d_N.png",
    )
    p.add_argument("--no-3d", action="store_true", help="skip the 3D render")
    p.add_argument("--no-animation", action="store_true", help="skip the animation")
    p.add_argument(
        "--no-data",
        action="store_true",
        help="skip images.h5 and peaks.csv (about 2 MB per image of a corridor pose)",
    )


def run(args: argparse.Namespace) -> int:
    from acousim.imaging.outputs import our_files, tidy
    from acousim.imaging.run import prepare_pictures
    from processing.base.atomic import committed_together

    out = writable_dir(args.out)
    before = our_files(out)  # our files of an earlier run: replaced or removed
    recs, index, options, image_all = load_and_image(args)
    shown = _shown(args.recording, index)
    prepare_pictures(render_3d=not args.no_3d, animation=_animated(args, recs))  # before work
    with _beside_imaging(recs, index, options, not args.no_data) as (add, made):
        images = image_all(each=add)
    with committed_together():  # every file or none (Ctrl-C, an error)
        files = _write_all(args, out, recs, images, index, options, shown, made)
    for f in files:
        print(f"  {f}")
    for line in tidy(out, before, files).lines():  # the user's own files stay
        print(f"  ({line})")
    print(f"{len(files)} file(s) written to {out} ({elapsed():.1f} s from the start)")
    return 0


def _shown(text: str | None, index: list[int]) -> list[int] | None:
    """Positions in the imaged recordings of --recording's file indices (None: not
    given); an index not imaged is a usage error naming it."""
    wanted = parse_indices("--recording", text)
    if wanted is None:
        return None
    missing = [i for i in wanted if i not in index]
    if missing:
        raise UsageError(
            f"not among the recordings imaged ({_span(index)}; --index chooses them)",
            key="--recording",
            value=missing,
        )
    return [index.index(i) for i in dict.fromkeys(wanted)]


def _span(index: list[int]) -> str:
    """'0 to 59' for a contiguous run, else the indices."""
    if index == list(range(index[0], index[-1] + 1)):
        return f"{index[0]} to {index[-1]}" if len(index) > 1 else str(index[0])
    return ",".join(map(str, index))


@contextlib.contextmanager
def _beside_imaging(recs, index, options, wanted: bool):
    """While the recordings are imaged (one core), each imaged recording's label maps
    and peak tables for images.h5 and peaks.csv made in a thread (the other core).
    Yields the callback for :func:`acousim.imaging.run.image_recordings`'s `each`
    (None: not `wanted`) and a list that holds, once the block ends, the (label maps,
    peak tables) made, in order: those of the first recordings (those not begun are
    cancelled, made later by images.h5's process; the thread has ended: nothing runs
    beside a fork)."""
    made: list = []
    if not wanted:
        yield None, made
        return
    from concurrent.futures import ThreadPoolExecutor

    from acousim.export.images import label_maps, peak_tables

    def make(i: int, imgs: dict) -> tuple:
        labels = next(label_maps([recs[i]], [imgs], options.dynamic_range_db))
        return labels, peak_tables([recs[i]], [imgs], [index[i]], options.peak_threshold_db)[0]

    futures: list = []
    pool = ThreadPoolExecutor(1)
    try:
        yield (lambda i, imgs: futures.append(pool.submit(make, i, imgs))), made
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    for f in futures:
        if f.cancelled():
            break
        made.append(f.result())


def _animated(args, recs: list) -> bool:
    """Whether the command draws the drive's animation."""
    return not args.no_animation and len(recs) > 1


def _write_all(args, out, recs, images, index, options, shown=None, made=()) -> list:
    """The pictures, and meanwhile, in a second process (:mod:`acousim.cli.ahead`),
    images.h5 and peaks.csv (written to temporary files renamed here with the rest)."""
    from acousim.cli.ahead import ahead_in_a_process
    from processing.base.atomic import atomic_path

    if args.no_data:
        return _write_pictures(args, out, recs, images, index, options, shown)
    data = [out / "images.h5", out / "peaks.csv"]
    with atomic_path(data[0]) as h5, atomic_path(data[1]) as csv:
        bar = progress("images.h5", "recording")  # from the start of its work
        work = functools.partial(_data_steps, h5, csv, recs, images, index, options, made)
        with ahead_in_a_process(work) as steps:
            pictures = _write_pictures(args, out, recs, images, index, options, shown)
            for done, total in steps:
                bar(done, total)
    return data + pictures


def _data_steps(h5, csv, recs, images, index, options, made=()):
    """Write images.h5 to `h5` and peaks.csv to `csv` (paths), the peak tables made
    once for both, each when its recording's turn comes (the label maps made one
    ahead, in a thread); `made`: the (label maps, peak tables) of the first
    recordings, made while imaging (:func:`_beside_imaging`); yields ``(done,
    total)`` as images.h5's recordings are written."""
    import itertools
    from pathlib import Path

    from acousim.export.images import (
        Given,
        Stored,
        image_data_steps,
        label_maps_ahead,
        peak_tables,
        peaks_csv_text,
    )

    threshold, k = options.peak_threshold_db, len(made)
    tables: list = []  # each recording's, kept for peaks.csv as its group is written

    def each_table():  # those made while imaging, then each made when its turn comes
        for rec, imgs, i in zip(recs[k:], images[k:], index[k:]):
            tables.append(peak_tables([rec], [imgs], [i], threshold)[0])
            yield tables[-1]

    tables += [t for _, t in made]
    labels = label_maps_ahead(recs, images, options.dynamic_range_db, [m for m, _ in made])
    given = Given(tables=itertools.chain(list(tables), each_table()), labels=labels)
    stored = Stored(dynamic_range_db=options.dynamic_range_db, peak_threshold_db=threshold)
    yield from image_data_steps(h5, recs, images, index, stored=stored, given=given)
    Path(csv).write_text(peaks_csv_text(tables), encoding="utf-8")


def _write_pictures(args, out, recs, images, index, options, shown) -> list:
    """The stills of the recordings `shown` and, meanwhile in a second process
    (:mod:`acousim.cli.ahead`), the drive's animation (written to a temporary file
    renamed here with the rest)."""
    from acousim.cli.ahead import ahead_in_a_process
    from acousim.imaging.run import drive_steps, write_stills
    from processing.base.atomic import atomic_path

    def stills() -> list:
        return write_stills(
            recs,
            images,
            out,
            options,
            shown=shown or [0],
            indices=index,
            render_3d=not args.no_3d,
            progress=progress("stills", "picture"),
        )

    if not _animated(args, recs):
        return stills()
    gif = out / "drive.gif"
    with atomic_path(gif) as tmp:
        # forked before the stills' 3D view: the worker's VTK starts afresh
        work = functools.partial(drive_steps, recs, images, tmp, options, indices=index)
        bar = progress("animate", "frame")  # from the worker's start
        with ahead_in_a_process(work) as frames:
            files = stills()
            for done, total in frames:
                bar(done, total)
    return [*files, gif]
