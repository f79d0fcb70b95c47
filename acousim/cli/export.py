"""``acousim export``: recordings and their images to a ROS 2 bag (MCAP)."""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import UsageError, writable_dir
from .image import imaging_arguments, load_and_image
from .options import DeclaredHelp


def register(sub) -> None:
    p = sub.add_parser(
        "export",
        formatter_class=DeclaredHelp,
        help="write recordings and their images to a ROS 2 bag (MCAP)",
        description="Image recordings and write a rosbag2 folder (MCAP storage) "
        "with the raw samples (std_msgs/Float32MultiArray), the image peaks "
        "(sensor_msgs/PointCloud2), the fan image (sensor_msgs/Image), the sensor "
        "pose (/tf) and the sensor's description (std_msgs/String, JSON). Needs "
        "the rosbags package (pip install 'acousim[ros]'); no ROS installation. "
        "Layout: docs/export.md.",
    )
    imaging_arguments(p)
    p.add_argument("--out", required=True, help="bag folder to create (must not exist)")
    p.add_argument(
        "--image-method",
        default=None,
        help="the method published as peaks and fan (default: the sharpest imaged)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.exists():
        raise UsageError(f"--out {str(out)!r} exists already; a bag is never overwritten")
    writable_dir(out.parent)
    try:
        from acousim.export.rosbag import write_rosbag
    except ImportError as exc:
        raise UsageError(str(exc)) from None
    recs, index, options, image_all = load_and_image(args)
    if args.image_method and args.image_method not in options.methods:
        raise UsageError(
            f"--image-method {args.image_method!r} is not among --method {args.method!r}"
        )
    images = image_all()
    write_rosbag(
        out,
        recs,
        images,
        index,
        method=args.image_method,
        threshold_db=options.peak_threshold_db,
    )
    print(f"{len(recs)} recording(s) written to the ROS 2 bag {out} (MCAP)")
    return 0
