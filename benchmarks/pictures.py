"""Pictures and export files of the corridor drive: time per picture and per file,
and the size of each file per pose (``ACOUSIM_BENCH_PICTURE_POSES`` poses, default 10);
then the commands as a user runs them: ``acousim image`` of the 60-pose drive against
``acousim simulate corridor`` (``ACOUSIM_BENCH_COMMAND_PAIRS`` alternating pairs,
default 3; 0 leaves them out)."""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from acousim.export import write_image_data, write_peaks_csv
from acousim.export.rosbag import write_rosbag
from acousim.imaging.run import (
    ImagingOptions,
    _render,
    _scene,
    _scene_triangles,
    _truth_sensor,
    drive_steps,
    image_recordings,
    prepare_pictures,
)
from acousim.scene import load_scene
from acousim.simulator import Simulator
from acousim.viz import elaz_figure, fan_figure

from .timing import best_time

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"


def run() -> str:
    n = int(os.environ.get("ACOUSIM_BENCH_PICTURE_POSES", "10"))
    prepare_pictures()
    recs = Simulator(load_scene(SCENE)).run(list(range(n)))
    options = ImagingOptions()
    images = image_recordings(recs, options)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        first, imgs = recs[0], images[0]
        truth = _truth_sensor(first)
        tri = _scene_triangles(_scene(first))

        def timed(name, fn, path=None, per=1):
            t = best_time(fn, repeat=3)
            size = f"{path.stat().st_size / per / 1e6:.2f}" if path and path.is_file() else ""
            rows.append(f"| {name} | {t / per * 1e3:.0f} | {size} |")

        timed("fan.png (3 methods)", lambda: fan_figure(imgs, out / "f.png", truth=truth))
        timed("elaz_music-fbss.png", lambda: elaz_figure(imgs["music-fbss"], out / "e.png"))
        timed("scene3d.png", lambda: _render(first, imgs, tri, out / "s.png", options))
        for view in ("plan", "3d"):
            timed(
                f"drive.gif, per frame (`--drive-view {view}`)",
                lambda v=view: list(drive_steps(recs, images, out / "d.gif", options, view=v)),
                per=n,
            )
        timed(
            "images.h5, per pose (3 methods)",
            lambda: write_image_data(out / "images.h5", recs, images),
            out / "images.h5",
            per=n,
        )
        timed(
            "peaks.csv, per pose",
            lambda: write_peaks_csv(out / "peaks.csv", recs, images),
            out / "peaks.csv",
            per=n,
        )
        bag = out / "bag"

        def write_bag():
            import shutil

            shutil.rmtree(bag, ignore_errors=True)
            write_rosbag(bag, recs, images)

        t = best_time(write_bag, repeat=3)
        size = sum(p.stat().st_size for p in bag.iterdir()) / n / 1e6
        rows.append(f"| ROS 2 bag (MCAP), per pose | {t / n * 1e3:.0f} | {size:.2f} |")
    return "\n".join(
        [
            f"## Pictures and export files: corridor drive, {n} poses, uRTIS",
            "",
            "Best of 3 runs of each writer on images already computed (DAS, Capon-FBSS, "
            "MUSIC-FBSS, 2 degree grid); the drive animation includes its figure, the plan "
            "(the default) or the 3D view, and the GIF's encoding (the peaks found again: "
            "the command hands its peak tables on), the bag the fan raster and peaks of "
            "MUSIC-FBSS and the raw samples as float32.",
            "",
            "| output | ms | MB |",
            "|---|---|---|",
            *rows,
            "",
            *_commands(int(os.environ.get("ACOUSIM_BENCH_COMMAND_PAIRS", "3"))),
        ]
    )


def _commands(pairs: int) -> list[str]:
    """``acousim simulate corridor`` and ``acousim image`` of its file, each as a
    process, alternating `pairs` times: wall and CPU (the process and its workers)
    medians, and the median of the pairs' wall ratios."""
    if pairs <= 0:
        return []
    acousim = [sys.executable, "-m", "acousim.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        rec = str(Path(tmp) / "corridor.h5")
        simulate = [*acousim, "simulate", "corridor", "--out", rec, "-q"]
        image = [*acousim, "image", rec, "--out", str(Path(tmp) / "img"), "-q"]
        _timed(simulate)  # the recording file, and a warm-up of both
        _timed(image)
        runs = [(_timed(simulate), _timed(image)) for _ in range(pairs)]
    sim, img = zip(*runs)
    ratio = statistics.median(i[0] / s[0] for s, i in runs)

    def row(name: str, times) -> str:
        wall, cpu = (statistics.median(t[k] for t in times) for k in (0, 1))
        return f"| {name} | {wall:.1f} | {cpu:.1f} |"

    return [
        "The commands as a user runs them (60 poses, the defaults: DAS, Capon-FBSS and "
        f"MUSIC-FBSS; the stills, the animation with its plan and peaks.csv), {pairs} "
        "alternating pairs "
        "of processes after a warm-up, medians; CPU counts the workers. Target: `image` "
        "no slower than `simulate`.",
        "",
        "| command | wall (s) | CPU (s) |",
        "|---|---|---|",
        row("`acousim simulate corridor`", sim),
        row("`acousim image` of its file", img),
        f"| image / simulate (wall, median of the pairs) | {ratio:.2f}x | |",
        "",
    ]


def _timed(argv: list[str]) -> tuple[float, float]:
    """Wall and CPU seconds (user + system, the process and every child it waited
    for) of one run of `argv`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu
