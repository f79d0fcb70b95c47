"""``acousim scenes``: list the bundled scenes and dataset specs.

List the bundled scenes and what each shows (`acousim simulate NAME` runs one by its
name), then the bundled dataset specs (`acousim dataset NAME --out FOLDER` generates
one).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from acousim.cli.common import add_command, bundled_scenes


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument("-v", "--verbose", action="store_true", help="also say where they are")


def run(args: argparse.Namespace) -> int:
    from acousim.bundled import scene_files
    from acousim.scene import SceneError, load_scene
    from processing.base.errors import InputError

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
    _datasets(args.verbose)
    return 0


def _datasets(verbose: bool) -> None:
    """The bundled dataset specs, one line each."""
    from acousim.bundled import data_dir
    from acousim.dataset.spec import load_spec
    from processing.base.errors import InputError

    folder = data_dir("datasets")
    print("dataset specs (acousim dataset NAME --out FOLDER):")
    for f in sorted(folder.glob("*.toml")):
        try:
            spec = load_spec(f)
        except InputError as exc:
            print(f"{f.name:18s} invalid ({exc})")
            continue
        scenes = ", ".join(f"{Path(s.file).stem} ({s.poses} poses)" for s in spec.scenes)
        what = "CHIRP files" if spec.format == "chirp" else "images " + ", ".join(spec.store.images)
        print(
            f"{f.name:18s} {spec.samples} samples in {spec.n_shards} shard(s) of {scenes}: {what}"
        )
    if verbose:
        print(f"(in {folder}; `acousim dataset corridor_small --out data` runs it)")
