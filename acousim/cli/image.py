"""``acousim image``: image recordings and write pictures and data files.

Run the processing pipeline on simulated or real recordings and write fan images
(azimuth x range), elevation-azimuth maps, a 3D render, for a trajectory an animated
GIF, the image peaks (peaks.csv) and, with --images-h5, the images as data (images.h5:
range x elevation x azimuth in dB with its axes and truth labels). File layouts:
docs/export.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
from typing import TYPE_CHECKING

from acousim.cli.common import (
    UsageError,
    add_command,
    choice,
    from_start,
    methods,
    parse_indices,
    progress,
    replaceable_in,
    writable_dir,
)
from acousim.cli.options import add_declared
from acousim.cli.ours import is_ours
from processing.base.errors import InputError

if TYPE_CHECKING:
    from acousim.viz.drive import DriveView

IMAGING = "acousim.imaging.run:ImagingOptions"


def imaging_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `image` and `export`."""
    p.add_argument("file", help="recording file (.h5: ours, or a CHIRP file)")
    p.add_argument(
        "--method",
        default=None,  # ImagingOptions.methods (spelt out in the help; a test holds it)
        help="comma-separated methods: narrowband das, music[-fss|-fbss], "
        "capon[-fss|-fbss]; wideband capon[-fbss]-wb, music[-fbss]-wb; broadband das-bb, "
        "das-cf-bb, dmas2..5-bb, dmas2..5-cf-bb (default: das,capon-fbss,music-fbss), "
        "for an array that is not a uniform rectangular one (the eRTIS) das,capon,music",
    )
    p.add_argument("--index", help="recordings to image: '0,3' or '0:10' (default: all)")
    p.add_argument(
        "--sensor",
        metavar="NAME",
        help="a rig's recordings: only those of the sonar NAME (of --index, if given)",
    )
    add_declared(
        p,
        "--azimuth",
        IMAGING,
        "azimuth_deg",
        nargs=2,
        metavar=("MIN", "MAX"),
        note="e.g. --azimuth -60 60",
    )
    add_declared(
        p,
        "--elevation",
        IMAGING,
        "elevation_deg",
        nargs=2,
        metavar=("MIN", "MAX"),
        note="e.g. --elevation -60 60; a reflector outside the span is seen at its edge",
    )
    add_declared(p, "--step", IMAGING, "step_deg")
    add_declared(
        p,
        "--frequency-khz",
        IMAGING,
        "frequency_hz",
        scale=1e3,
        note="e.g. 31.25; not given: the strongest STFT bin of the call's "
        "band below the array's alias-free limit",
    )
    add_declared(
        p,
        "--n-sources",
        IMAGING,
        "n_sources",
        note="the music methods; not given: the mean-eigenvalue rule",
    )
    add_declared(
        p,
        "--subarray",
        IMAGING,
        "subarray",
        nargs=2,
        metavar=("ROWS", "COLUMNS"),
        note="the -fss/-fbss methods, e.g. --subarray 5 5",
    )
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
#: acousim.viz.drive.DRIVE_VIEWS, written out: the command line starts without the
#: pictures' imports (tests/system/test_api.py keeps the two equal)
DRIVE_VIEWS = ("plan", "3d")


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


@dataclasses.dataclass
class Imaged:
    """What :func:`load_and_image`'s imaging made: per recording (in the order of the
    indices), the recording, its images by method (those kept) and what `beside`
    made of it (None without one)."""

    recordings: list
    images: list
    extras: list


def load_and_image(args: argparse.Namespace, *, lazy: bool = False):
    """`image` and `export`: the options, the recordings of --index (None when `lazy`:
    each is then read by the process that images it), their indices in the file, and
    a function that images them (called once the command is ready: an
    :class:`Imaged`)."""
    import processing as P
    from acousim.allocator import small_pages
    from acousim.core.forked import shared_by_two_processes
    from acousim.imaging.run import recording_images
    from acousim.process import configure

    # the process's policy, as a simulating command's: BLAS on one thread (the same
    # bytes on every host), freed memory kept for reuse (the label maps' and the
    # pictures' arrays of tens of MB: half the page faults' time); and those arrays
    # on small pages (a huge page's fault cost more system time than it saved)
    configure()
    small_pages()
    options = _imaging_options(args)
    index = _indices(args.file, parse_indices("--index", args.index))
    call = call_waveform(args.call)

    def read(i: int):
        try:
            return P.load_recording(args.file, i, call=call)
        except P.RecordingFileError as exc:
            raise UsageError(str(exc)) from None

    sensor = getattr(args, "sensor", None)
    recs = None if lazy and sensor is None else [read(i) for i in index]  # only those asked
    if sensor is not None:
        recs, index = _of_sensor(recs, index, sensor)

    def image_all(first=None, beside=None, keep=None) -> Imaged:
        """Image the recordings, each read (when lazy) and imaged by this process or a
        forked worker, whichever takes it first (:func:`shared_by_two_processes`);
        `first` is called here meanwhile, before this process takes a recording;
        `beside(k, recording, images)` is made of each where it was imaged; with
        `keep`, only the images ``keep(k, images)`` of each are handed on."""
        bar = progress("image", "recording")  # the bar's time starts with the work

        def make(k: int) -> tuple:
            rec = read(index[k]) if recs is None else recs[k]
            imgs = recording_images(rec, options, k)
            extra = None if beside is None else beside(k, rec, imgs)
            return rec if recs is None else None, imgs if keep is None else keep(k, imgs), extra

        made = shared_by_two_processes(make, len(index), first=first, progress=bar)
        got = recs if recs is not None else [rec for rec, _, _ in made]
        return Imaged(got, [imgs for _, imgs, _ in made], [extra for _, _, extra in made])

    return recs, index, options, image_all


def _indices(file: str, index: list[int] | None) -> list[int]:
    """The recordings of `file` to image (`index`, None: all); a UsageError for an
    index the file does not hold, or a file that holds none."""
    import processing as P

    try:
        n = P.count_recordings(file)
    except P.RecordingFileError as exc:
        raise UsageError(not_read_here(file) or str(exc)) from None
    if n == 0:
        raise UsageError(f"{file}: the file holds no recordings")
    if index is not None:
        bad = [i for i in index if not 0 <= i < n]
        if bad:
            raise UsageError(f"the file holds {n} recording(s)", key="--index", value=bad)
    return list(range(n)) if index is None else index


#: what `image` and `export` read, said when they are given something else
READS = "a recording file (.h5 of `acousim simulate` or `record`) or a CHIRP file"


def not_read_here(file: str) -> str | None:
    """What `file` is when it is one of our outputs these commands do not read (a ROS 2
    bag, an images.h5, a folder), as one line naming it and what they read; None for
    anything else (the reader's own message says what is wrong)."""
    from pathlib import Path

    path = Path(file)
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return (
                f"{file}: a ROS 2 bag (a folder, as `acousim export` writes it), which this "
                f"command does not read; give {READS}"
            )
        return f"{file}: a folder, not a file; give {READS}"
    if is_ours("images", path):
        return (
            f"{file}: an images.h5 (images written by `acousim image --images-h5`), not a "
            f"recording file; give {READS}"
        )
    return None


#: the flag of each ImagingOptions field given unscaled on the command line: an
#: InputError of the options names the flag (its value as typed)
FLAGS = {
    "azimuth_deg": "--azimuth",
    "elevation_deg": "--elevation",
    "subarray": "--subarray",
    "step_deg": "--step",
    "n_sources": "--n-sources",
    "energy_fraction": "--energy-fraction",
    "min_range_m": "--min-range",
    "max_range_m": "--max-range",
    "peak_threshold_db": "--peak-threshold",
    "dynamic_range_db": "--dynamic-range-db",
}


def _imaging_options(args: argparse.Namespace):
    """The ImagingOptions of the command's arguments (unset ones keep their declared
    defaults); a UsageError naming the option for a value the options refuse (a span
    whose MIN is above its MAX, a fractional subarray) or a range window that is empty."""
    from acousim.imaging.run import ImagingOptions

    given = {
        "azimuth_deg": args.azimuth,
        "elevation_deg": args.elevation,
        "frequency_hz": args.frequency_khz,
        "n_sources": args.n_sources,
        "subarray": args.subarray,
        "step_deg": args.step,
        "energy_fraction": args.energy_fraction,
        "min_range_m": args.min_range,
        "max_range_m": args.max_range,
        "peak_threshold_db": args.peak_threshold,
        "dynamic_range_db": args.dynamic_range_db,
    }
    if args.method is not None:
        given["methods"] = methods("--method", args.method)
    try:
        options = ImagingOptions(**{k: v for k, v in given.items() if v is not None})
    except InputError as exc:
        name = (exc.key or "").removeprefix("ImagingOptions.")
        if name not in FLAGS:
            raise
        value = given[name]
        typed = " ".join(f"{v:g}" for v in value) if isinstance(value, list) else value
        raise UsageError(exc.reason, key=FLAGS[name], value=typed) from None
    if options.max_range_m is not None and options.max_range_m <= options.min_range_m:
        raise UsageError(
            f"must be above --min-range {options.min_range_m:g}",
            key="--max-range",
            value=args.max_range,
        )
    return options


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    imaging_arguments(p)
    p.add_argument(
        "--out",
        default="out",
        help="output folder (default: out); its files of an earlier run are replaced or "
        "removed, the others kept; a file there by one of our names that is not of its "
        "kind (our tables and images.h5; a picture: any PNG or GIF) is never overwritten "
        "(the run is refused)",
    )
    p.add_argument(
        "--recording",
        help="the recording(s) the fan, el-az and 3D pictures show, by index in the file: "
        "'2', '0,5' or a range '2:5' (end excluded); among those imaged (default: the "
        "first imaged); several write fan_N.png, elaz_METHOD_N.png, scene3d_N.png",
    )
    p.add_argument("--no-3d", action="store_true", help="skip the 3D render")
    p.add_argument("--no-animation", action="store_true", help="skip the animation")
    p.add_argument(
        "--drive-view",
        type=choice("drive view", DRIVE_VIEWS),
        default="plan",
        metavar="{plan,3d}",
        help="the animation's left panel: 'plan' (the scene cut at the sensor's height, "
        "from above in the sensor's frame; default) or '3d' (a 3D view behind the "
        "sensor, rendered per frame: about 60 ms of CPU more a frame)",
    )
    p.add_argument(
        "--images-h5",
        action="store_true",
        help="also write images.h5: every image as data, with its truth labels (about "
        "5 MB per corridor pose, and the command's longest part)",
    )
    p.add_argument("--no-data", action="store_true", help="skip peaks.csv (and images.h5)")


def run(args: argparse.Namespace) -> int:
    from acousim.imaging.outputs import our_files, replaced_kinds, tidy
    from acousim.imaging.run import prepare_pictures
    from processing.base.atomic import committed_together

    if args.images_h5 and args.no_data:
        raise UsageError("--no-data skips every data file", key="--images-h5", value=True)
    out = writable_dir(args.out)  # made now, removed again if the run fails
    replaceable_in("--out", out, replaced_kinds(out))  # what it would replace: ours
    recs, index, options, image_all = load_and_image(args, lazy=True)
    shown = _shown(args.recording, index)
    animated = _animated(args, index)
    before = our_files(out)  # our files of an earlier run: replaced or removed

    def first() -> None:  # while the worker images: the pictures' imports (before the
        # drive's worker is forked: it inherits them)
        prepare_pictures(render_3d=not args.no_3d, animation=animated, drive_view=args.drive_view)

    beside = None if args.no_data else _peak_tables(index, options)
    keep = None if args.images_h5 else drawn_images(shown or [0], fan=beside is not None)
    imaged = image_all(first=first, beside=beside, keep=keep)
    recs, images = imaged.recordings, imaged.images
    tables = None if args.no_data else imaged.extras
    with committed_together():  # every file or none (Ctrl-C, an error)
        files = _write_all(args, out, recs, images, index, options, shown, tables)
    for f in files:
        print(f"  {f}")
    for line in tidy(out, before, files).lines():  # the user's own files stay
        print(f"  ({line})")
    print(f"{len(files)} file(s) written to {out} {from_start()}")
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


def drawn_images(shown: list[int], *, fan: bool = False):
    """``keep(k, images)``: the images the pictures draw of recording k, every
    method's for a recording `shown` (by position), else the animation's method's
    alone (the others travel from the imaging worker for nothing); with `fan` (the
    animation's peaks are in the peak tables), only its fan
    (:func:`acousim.viz.fan.fan_only`: a twentieth of the cells, the same frame)."""
    from acousim.imaging.run import drive_method
    from acousim.viz.fan import fan_only

    def keep(k: int, imgs: dict) -> dict:
        if k in shown:
            return imgs
        method = drive_method(imgs)
        return {method: fan_only(imgs[method]) if fan else imgs[method]}

    return keep


def _peak_tables(index: list[int], options):
    """``make(k, recording, images)``: recording k's peak tables ({method: rows},
    matched to the traced paths: :func:`acousim.export.images.peak_tables`), for
    peaks.csv, images.h5 and the drive's peaks."""
    from acousim.export.images import peak_tables

    def make(k: int, rec, imgs: dict) -> dict:
        return peak_tables([rec], [imgs], [index[k]], options.peak_threshold_db)[0]

    return make


def _animated(args, index: list) -> bool:
    """Whether the command draws the drive's animation (of the recordings `index`)."""
    return not args.no_animation and len(index) > 1


def _write_all(args, out, recs, images, index, options, shown=None, tables=None) -> list:
    """peaks.csv (from the peak `tables`; None: not asked), the pictures and, with
    --images-h5, meanwhile in a second process (:mod:`acousim.core.forked`), images.h5
    (written to a temporary file renamed here with the rest)."""
    from acousim.core.forked import ahead_in_a_process
    from acousim.export.images import peaks_csv_text
    from processing.base.atomic import atomic_path

    files = []
    if tables is not None:
        files.append(out / "peaks.csv")
        with atomic_path(files[-1]) as csv:
            csv.write_text(peaks_csv_text(tables), encoding="utf-8")
    if not args.images_h5:
        return files + _write_pictures(args, out, recs, images, index, options, shown, tables)
    with atomic_path(out / "images.h5") as h5:
        bar = progress("images.h5", "recording")  # from the start of its work
        work = functools.partial(_data_steps, h5, recs, images, index, options, tables)
        with ahead_in_a_process(work) as steps:
            pictures = _write_pictures(args, out, recs, images, index, options, shown, tables)
            for done, total in steps:
                bar(done, total)
    return [out / "images.h5", *files, *pictures]


def _data_steps(h5, recs, images, index, options, tables):
    """Write images.h5 to `h5` (a path) with the recordings' peak `tables` (the label
    maps made one ahead, in a thread); yields ``(done, total)`` as its recordings are
    written."""
    from acousim.export.images import Given, Stored, image_data_steps, label_maps_ahead

    labels = label_maps_ahead(recs, images, options.dynamic_range_db)
    given = Given(tables=iter(tables), labels=labels)
    stored = Stored(
        dynamic_range_db=options.dynamic_range_db, peak_threshold_db=options.peak_threshold_db
    )
    yield from image_data_steps(h5, recs, images, index, stored=stored, given=given)


@dataclasses.dataclass(frozen=True)
class Asked:
    """The pictures a command asked for: the stills of the recordings `shown`
    (positions among those imaged), with the 3D view (`render_3d`), and the drive's
    animation (`animated`) with its left panel `drive_view`
    (:data:`acousim.viz.drive.DriveView`)."""

    shown: list[int]
    render_3d: bool = True
    animated: bool = True
    drive_view: DriveView = "plan"


def write_pictures_beside(out, recs, images, index, options, asked: Asked, tables=None) -> list:
    """The pictures :class:`Asked` for (the stills and the drive's animation, its
    peaks from the peak `tables`, if made), drawn by this process and a forked worker
    together, each taking the next picture not yet taken, the longest first (the
    animation, the 3D views, the fans, the maps): the files written, in the stills'
    order then the animation.  They are written whole into a stage in `out`
    (:func:`processing.base.atomic.staged`) and renamed into place with the
    command's other files."""
    from acousim.core.forked import shared_by_two_processes
    from acousim.imaging.run import PictureJob, drive_jobs, still_jobs
    from processing.base.atomic import staged

    with staged(out) as stage:
        jobs = still_jobs(
            recs,
            images,
            stage.folder,
            options,
            shown=asked.shown,
            indices=index,
            render_3d=asked.render_3d,
        )
        if asked.animated:  # one animation per sonar of a rig (drive_parts)
            drives = drive_jobs(
                recs,
                images,
                stage.folder,
                options,
                indices=index,
                view=asked.drive_view,
                tables=tables,
            )
            jobs += [PictureJob(drive.path, drive) for drive in drives]
        order = sorted(range(len(jobs)), key=lambda k: _cost_rank(jobs[k].path.name))
        made = shared_by_two_processes(
            lambda k: jobs[order[k]](), len(jobs), progress=progress("pictures", "picture")
        )
        files = [None] * len(jobs)
        for k, path in zip(order, made):
            files[k] = stage.adopt(path, out / path.name)
    return files


#: the pictures by what each costs, the longest first (drawn in this order by two
#: processes, the longest is not left for last): file name's stem -> rank
_COST_RANK = {"drive": 0, "scene3d": 1, "fan": 2, "elaz": 3}


def _cost_rank(name: str) -> int:
    """A picture's place in :data:`_COST_RANK` by its file `name` (``fan_3.png``)."""
    return _COST_RANK.get(name.split(".")[0].split("_")[0], len(_COST_RANK))


def _write_pictures(args, out, recs, images, index, options, shown, tables=None) -> list:
    """The command's pictures (:func:`write_pictures_beside`)."""
    asked = Asked(shown or [0], not args.no_3d, _animated(args, index), args.drive_view)
    return write_pictures_beside(out, recs, images, index, options, asked, tables)
