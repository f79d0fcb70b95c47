"""``acousim info``: what a recording file, a dataset shard or a dataset folder holds."""

from __future__ import annotations

import argparse


def register(sub) -> None:
    p = sub.add_parser(
        "info",
        help="describe a recording file, a dataset shard or a dataset folder",
        description="Print what a recording file (HDF5), a dataset shard (.h5) or a "
        "dataset folder (with its manifest.json) holds.",
    )
    p.add_argument("file", help="recording file, dataset shard or dataset folder")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from acousim.dataset.info import describe

    for line in describe(args.file):  # an InputError is reported by main()
        print(line)
    return 0
