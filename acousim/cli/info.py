"""``acousim info``: describe any file or folder acousim writes (recordings, images.h5, a
folder of acousim image, a ROS 2 bag, a dataset).

Print what a recording file (HDF5; simulated, real or emulated), an image file
(images.h5), a folder written by acousim image (its pictures, peaks.csv and
images.h5), a ROS 2 bag folder (acousim export), a dataset shard (.h5) or a dataset
folder (with its manifest.json) holds.
"""

from __future__ import annotations

import argparse

from acousim.cli.common import add_command


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument(
        "file",
        help="recording file, images.h5, acousim image's folder, bag folder, dataset shard "
        "or dataset folder",
    )


def run(args: argparse.Namespace) -> int:
    from acousim.dataset.info import describe

    for line in describe(args.file):  # an InputError is reported by main()
        print(line)
    return 0
