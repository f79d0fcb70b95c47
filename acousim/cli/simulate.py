"""``acousim simulate``: simulate a scene file into an HDF5 recording file.

Run a scene file for its pose or its whole trajectory and write every recording, with
its ground truth, to one HDF5 file.
"""

from __future__ import annotations

import argparse

from acousim.cli.common import (
    add_command,
    add_seed,
    from_start,
    load_scene,
    output_file,
    parse_indices,
    preload_simulation,
    simulate,
    stop_if_interrupted,
)
from acousim.cli.options import add_quality


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument(
        "scene",
        help="scene file (.toml, see docs/scene-format.md) or a bundled scene's name "
        "(acousim scenes)",
    )
    p.add_argument(
        "--out",
        help="output file (default: SCENE_NAME.h5); its missing folders are made, and "
        "removed again if the run fails or is interrupted; an existing file is replaced "
        "only if it is a recording file acousim wrote",
    )
    p.add_argument(
        "--poses",
        help="pose indices: '0,3,5' or a range '0:10' (default: all); a rig's scene: "
        "firing indices, every sonar's firings in time order",
    )
    add_seed(p)
    add_quality(p)


def run(args: argparse.Namespace) -> int:
    import processing as P

    poses = parse_indices("--poses", args.poses)
    scene = load_scene(args.scene)
    out = output_file("--out", args.out or f"{scene.name}.h5", "recordings")
    preload_simulation()
    recs = simulate(scene, poses, args.seed, args.quality)
    stop_if_interrupted()
    P.save_recordings(out, recs)
    print(f"{len(recs)} recording(s) of {scene.name!r} written to {out} {from_start()}")
    return 0
