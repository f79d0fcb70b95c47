"""``acousim export``: write recordings to a ROS 2 bag (MCAP) or a CHIRP file.

--format rosbag (default): image recordings and write a rosbag2 folder (MCAP storage)
with the raw samples (std_msgs/Float32MultiArray), the image peaks and LiDAR scans
(sensor_msgs/PointCloud2), the fan image (sensor_msgs/Image), the sensor pose (/tf; a
rig: the body on /tf, the mounts on /tf_static), the sensor's description
(std_msgs/String, JSON), /clock, the scene's meshes
(visualization_msgs/MarkerArray) and the traced reflectors (sensor_msgs/PointCloud2);
needs the rosbags package (pip install 'acousim[ros]'), no ROS installation. --format
chirp: write the recordings as one CHIRP file (Cosys-Lab's HDF5 dataset format, read by
their chirppy): signals, array, call, times, poses, LiDAR scans and our ground truth;
a rig's recordings: one acoustic sensor per sonar, placed by its mount (--sensor NAME:
one sonar's); the imaging options (--method, --azimuth, --elevation, --step,
--frequency-khz, --n-sources, --subarray, --energy-fraction, --min-range, --max-range,
--peak-threshold, --dynamic-range-db, --image-method) do not apply and are refused.
An existing --out is replaced only when it is a CHIRP file acousim wrote and not the
input. Layout: docs/export.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from acousim.cli.common import (
    UsageError,
    add_command,
    from_start,
    output_file,
    progress,
    writable_dir,
)
from acousim.cli.image import imaging_arguments, load_and_image


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    imaging_arguments(p)
    p.add_argument(
        "--format",
        choices=("rosbag", "chirp"),
        default="rosbag",
        help="rosbag (default) or chirp",
    )
    p.add_argument(
        "--out",
        required=True,
        help="bag folder to create (must not exist), or the CHIRP file (.h5) to write "
        "(if it exists: only a CHIRP file acousim wrote, never the input, is replaced)",
    )
    p.add_argument(
        "--image-method",
        default=None,
        help="the method published as peaks and fan (default: the sharpest imaged)",
    )


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if args.format == "chirp":
        return _chirp(args, out)
    if out.exists():
        raise UsageError(f"--out {str(out)!r} exists already; a bag is never overwritten")
    writable_dir(out.parent)  # made now (a bad folder said first), removed if the run fails
    try:
        from acousim.export.rosbag import write_rosbag
    except ImportError as exc:
        raise UsageError(str(exc)) from None
    recs, index, options, image_all = load_and_image(args)
    if args.image_method and args.image_method not in options.methods:
        raise UsageError(
            f"--image-method {args.image_method!r} is not among --method "
            f"{','.join(options.methods)!r}"
        )
    images = _Counted(image_all().images, progress("bag", "recording"))
    write_rosbag(
        out,
        recs,
        images,
        index,
        method=args.image_method,
        threshold_db=options.peak_threshold_db,
        dynamic_range_db=options.dynamic_range_db,
    )
    images.bar(len(images), len(images))
    print(f"{len(recs)} recording(s) written to the ROS 2 bag {out} (MCAP) {from_start()}")
    return 0


class _Counted(list):
    """The images, counted as the bag writer takes them one recording after the other
    (its loop over them is the long part): `bar(k, n)` when image k is taken."""

    def __init__(self, items, bar) -> None:
        super().__init__(items)
        self.bar = bar

    def __iter__(self):
        for k, item in enumerate(super().__iter__()):
            self.bar(k, len(self))
            yield item


def _chirp(args: argparse.Namespace, out: Path) -> int:
    import processing as P

    _no_imaging(args)
    if out.is_dir():
        raise UsageError(f"--out {str(out)!r} is a folder; give the CHIRP file to write")
    _not_the_input(out, Path(args.file))
    output_file("--out", out, "chirp")  # its folder made now, removed if the run fails
    recs, _, _, _ = load_and_image(args)  # the images are not made
    try:
        P.write_chirp(out, recs, progress=progress("CHIRP", "step"))
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None
    print(f"{len(recs)} recording(s) written to the CHIRP file {out} {from_start()}")
    return 0


#: the options that choose how recordings are imaged (the argument's name, its
#: option): a CHIRP export writes the recordings, not images
IMAGING_OPTIONS = (
    ("method", "--method"),
    ("azimuth", "--azimuth"),
    ("elevation", "--elevation"),
    ("step", "--step"),
    ("frequency_khz", "--frequency-khz"),
    ("n_sources", "--n-sources"),
    ("subarray", "--subarray"),
    ("energy_fraction", "--energy-fraction"),
    ("min_range", "--min-range"),
    ("max_range", "--max-range"),
    ("peak_threshold", "--peak-threshold"),
    ("dynamic_range_db", "--dynamic-range-db"),
    ("image_method", "--image-method"),
)


def _no_imaging(args: argparse.Namespace) -> None:
    """A UsageError naming the first imaging option given to a CHIRP export."""
    for name, option in IMAGING_OPTIONS:
        value = getattr(args, name)
        if value is not None:
            raise UsageError(
                "does not apply to --format chirp (the recordings are written, not "
                "imaged); leave it out",
                key=option,
                value=value,
            )


def _not_the_input(out: Path, source: Path) -> None:
    """A UsageError when `out` is the input `source`: even a CHIRP file acousim wrote
    (which --out may replace, :func:`acousim.cli.common.replaceable`) is not
    overwritten by its own export."""
    if out.exists() and source.exists() and out.samefile(source):
        raise UsageError(
            f"--out {str(out)!r} is the input file {str(source)!r}: writing the CHIRP "
            "file there would lose it; name another file"
        )
