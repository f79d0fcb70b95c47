"""``acousim demo``: simulate the corridor drive and write its pictures.

Simulate the bundled corridor drive (uRTIS at 10 Hz), image it with DAS, Capon-FBSS and
MUSIC-FBSS, and write fan images, a 3D render and an animation.
"""

from __future__ import annotations

import argparse

from acousim.cli.common import (
    add_command,
    add_seed,
    bundled_scenes,
    elapsed,
    load_scene,
    preload_simulation,
    progress,
    replaceable_in,
    simulate,
    writable_dir,
)
from acousim.cli.options import add_quality


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument(
        "--out",
        default="out",
        help="output folder (default: out); a file there by one of our names "
        "(corridor.h5, the pictures') that is not of its kind (a recording of ours; a "
        "picture: any PNG or GIF) is never overwritten",
    )
    add_seed(p)
    add_quality(p)


def run(args: argparse.Namespace) -> int:
    import processing as P
    from acousim.cli.image import Asked, drawn_images, write_pictures_beside
    from acousim.core.forked import shared_by_two_processes
    from acousim.imaging.outputs import replaced_kinds
    from acousim.imaging.run import ImagingOptions, prepare_pictures, recording_images
    from processing.base.atomic import committed_together

    out = writable_dir(args.out)
    replaceable_in("--out", out, {"corridor.h5": "recordings", **replaced_kinds(out)})
    scene = load_scene(bundled_scenes() / "corridor.toml")
    preload_simulation()
    recs = simulate(scene, None, args.seed, args.quality)
    t1 = elapsed()
    options = ImagingOptions()
    keep = drawn_images([0])  # the pictures draw the first pose's images, and one a pose

    def image(k: int) -> dict:
        return keep(k, recording_images(recs[k], options, k))

    images = shared_by_two_processes(  # two processes, the pictures' imports meanwhile
        image, len(recs), first=prepare_pictures, progress=progress("image", "recording")
    )
    t2 = elapsed()
    with committed_together():  # every file or none (Ctrl-C, an error)
        P.save_recordings(out / "corridor.h5", recs)
        asked = Asked(shown=[0], animated=len(recs) > 1)
        every = list(range(len(recs)))
        files = [out / "corridor.h5"]
        files += write_pictures_beside(out, recs, images, every, options, asked)
    print(
        f"corridor drive: {len(recs)} poses simulated in {t1:.1f} s (from the start), imaged in "
        f"{t2 - t1:.1f} s, pictures in {elapsed() - t2:.1f} s:"
    )
    for f in files:
        print(f"  {f}")
    return 0
