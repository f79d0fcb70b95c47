"""``acousim scenes``: list the bundled scenes.

List the bundled scenes and what each shows; `acousim simulate NAME` runs one by its
name.
"""

from __future__ import annotations

import argparse

from .common import add_command, bundled_scenes


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument("-v", "--verbose", action="store_true", help="also say where they are")


def run(args: argparse.Namespace) -> int:
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
        if sc.rig is not None:
            what = (
                f"a rig of {len(sc.rig.sonars)} sonar(s) and {len(sc.rig.lidars)} LiDAR(s), "
                f"{len(sc.rig.measurements())} firing(s)"
            )
        else:
            what = f"{sc.sensor.array.name}, {len(sc.sensor.poses)} pose(s)"
        print(f"{f.name:18s} {what}: {sc.description}")
    if args.verbose:
        print(f"(in {bundled_scenes()}; `acousim simulate wall` runs wall.toml)")
    return 0
