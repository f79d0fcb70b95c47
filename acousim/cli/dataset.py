"""``acousim dataset``: generate a dataset of simulated measurements.

Generate a sharded, reproducible, resumable dataset from a spec file
(docs/dataset-format.md), on local processes or a Dask cluster. Run it again to resume
(refused when the spec or a file it reads, a scene, mesh or trajectory, has changed).
"""

from __future__ import annotations

import argparse

from acousim.cli.common import (
    add_command,
    preload_simulation,
    progress,
    replaceable_in,
    since_start,
    writable_dir,
)
from acousim.cli.options import add_declared, add_quality
from processing.base.errors import InputError


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument(
        "spec", help="dataset spec (.toml) or a bundled spec's name (e.g. corridor_small)"
    )
    p.add_argument(
        "--out",
        required=True,
        help="output folder (made with its parents if missing; removed again if still "
        "empty when the run fails or is interrupted); a folder of another dataset or "
        "with a manifest.json or inputs.json acousim did not write is refused",
    )
    add_declared(p, "--workers", "acousim.process:Workers", "workers")
    p.add_argument("--scheduler", help="address of a Dask scheduler (instead of --workers)")
    add_quality(
        p,
        note="not given: the spec's [dataset] quality, unset there: each scene "
        "file's; the scenes' explicit [simulation] settings apply whatever the "
        "preset. A folder made under another quality is not resumed",
    )
    p.set_defaults(interrupted=interrupted)


def interrupted(args: argparse.Namespace) -> str:
    """What an interrupted run leaves (main() prints it after "interrupted; "): the
    shards kept and the command that resumes."""
    import shlex

    from acousim.bundled import resolve
    from acousim.dataset.generation import kept_shards

    try:
        kept, total = kept_shards(resolve("datasets", args.spec), args.out)
    except InputError:  # no readable spec: nothing was generated
        return "nothing was generated"
    again = ["acousim", "dataset", args.spec, "--out", args.out]
    if args.workers is not None:
        again += ["--workers", str(args.workers)]
    if args.scheduler:
        again += ["--scheduler", args.scheduler]
    if args.quality is not None:
        again += ["--quality", args.quality]
    return (
        f"{kept} of {total} shards kept in {args.out} (each whole; checked again on "
        f"resume); resume with: {shlex.join(again)}"
    )


def run(args: argparse.Namespace) -> int:
    from acousim.bundled import resolve
    from acousim.dataset import generate
    from acousim.dataset.generation import INPUTS, MANIFEST, usable_spec
    from acousim.process import Workers

    spec = resolve("datasets", args.spec)  # a file, or a bundled spec's name
    usable_spec(spec)  # a bad spec fails before the output folder is made
    if args.scheduler:
        from acousim.dataset.safety import check_scheduler

        check_scheduler(args.scheduler)
    writable_dir(args.out)
    replaceable_in("--out", args.out, {MANIFEST: "manifest", INPUTS: "inputs"})
    preload_simulation()
    manifest = generate(
        spec,
        args.out,
        workers=Workers().workers if args.workers is None else args.workers,
        scheduler=args.scheduler,
        progress=progress("shards", "shard", start="first"),
        quality=args.quality,
    )
    s = manifest["summary"]
    print(
        f"{manifest['samples']} samples in {len(manifest['shards'])} shards in {args.out} "
        f"({since_start()}; {s['samples_computed']} computed now, "
        f"{s['samples_per_second']:.2f} samples/s, {s['bytes_per_sample'] / 1e3:.0f} kB per "
        "sample)"
    )
    if s.get("damaged_shards"):
        names = ", ".join(manifest["damaged_shards"])
        print(
            f"redone: {len(s['damaged_shards'])} damaged shard(s), whose bytes no longer "
            f"matched the sha256 of their sidecar: {names}"
        )
    return 0
