"""Run time against error: what each knob costs and what it buys, in one picture.

For the corridor drive (moving: the Doppler renderer) and the shoebox (four poses in
the room), one point per setting of each knob, every other knob at the scene's
defaults, and one per quality preset (`acousim.scene.defaults.QUALITY_PRESETS`); all
against a reference run with every knob at its most accurate (the scene under the
"reference" preset, and the knobs that are not scene settings at their finest).
Noise off (``snr_db = inf``) and the direct path left out (the same in every run,
tens of dB above the echoes) so that the errors are the simulation's.

Time: per measurement, `Simulator.run` over the poses after a warm-up pose, every
trace paid (the tracer's cache emptied), the world's preparation apart; each variant
in alternating pairs with the defaults, its time the defaults' median times the
median of the pairs' ratios (this shared machine's speed drifts within minutes).
Error, over all poses:

* waveform: the residual over all microphones and samples, dB re the reference's
  energy, ``10 log10(sum (x - x_ref)^2 / sum x_ref^2)``;
* image: the DAS image (2 degree grid, every range bin from 0.3 m on), its residual
  ``10 log10(sum (P - P_ref)^2 / sum P_ref^2)`` over the power images;
* peaks: the image's local maxima within 30 dB of its strongest cell; a peak of the
  reference is lost unless the run has one within one cell in range, elevation and
  azimuth whose level is within 1 dB; a run's peak is added unless the reference has
  one within a cell (both searched down to 31 dB, so that a peak at the threshold is
  not lost by a tenth of a dB).

Adding a knob: one line in :data:`KNOBS` (a scene setting, a field of
:class:`acousim.synth.options.RenderOptions`, or a module constant).
``python -m benchmarks front`` runs this section, keeps its points in
benchmarks/data/front.json and redraws docs/front.png from them (``make bench`` too);
``python -m benchmarks.front --redraw`` redraws docs/front.png from that file without
measuring (:func:`redraw`); ``python -m benchmarks.front --quick`` prints a quick look
(2 poses, a setting or two per knob) and draws front-quick.png in the current folder.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import json
import re
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import processing as P
from acousim.scene import Pose, load_scene
from acousim.scene.model import Diffraction, Scene
from acousim.simulator import Simulator
from processing.base.errors import InputError

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"
PICTURE = ROOT / "docs" / "front.png"
DATA = ROOT / "benchmarks" / "data" / "front.json"
PEAK_DB = -30.0  # peaks compared down to this level
PEAK_SLACK_DB = 1.0  # levels within this; searched this far below PEAK_DB
IMAGE_MIN_RANGE_M = 0.3
#: an error of exactly zero is drawn here (dB)
FLOOR_DB = -140.0


@dataclass(frozen=True)
class Variant:
    """One point: `knob` at `label`: scene settings, render options and module
    constants (``"module:NAME"``) changed from the scene's own; or a `quality` preset."""

    knob: str
    label: str
    simulation: Mapping[str, Any] = field(default_factory=dict)
    render: Mapping[str, Any] = field(default_factory=dict)
    constants: Mapping[str, Any] = field(default_factory=dict)
    quality: str | None = None
    #: the scenes it applies to (None: every one)
    only: tuple[str, ...] | None = None


LIVE = "acousim.trace.diffraction.pair_bound:LIVE_SPREAD"
MOVING = ("corridor",)  # the Doppler renderer's knobs: scenes in motion

#: the knobs and their settings (each line a point); the defaults are the scene's own
KNOBS: tuple[Variant, ...] = (
    Variant("ray budget", "500 rays", {"rays": 500}),
    Variant("ray budget", "1000 rays", {"rays": 1000}),
    Variant("ray budget", "4000 rays", {"rays": 4000}),
    Variant("ray budget", "16000 rays", {"rays": 16000}),
    Variant("bounces", "1 bounce", {"bounces": 1}),
    Variant("bounces", "file's + 1", {"bounces": "+1"}),
    Variant("energy floor", "-50 dB", {"energy_floor_db": -50.0}),
    Variant("energy floor", "-60 dB", {"energy_floor_db": -60.0}),
    Variant("energy floor", "-70 dB", {"energy_floor_db": -70.0}),
    Variant("energy floor", "-100 dB", {"energy_floor_db": -100.0}),
    Variant("diffraction", "off", {"diffraction": Diffraction(enabled=False)}),
    Variant("diffraction", "order 1", {"diffraction": Diffraction(order=1)}),
    Variant("diffraction", "+ reflections", {"diffraction": Diffraction(reflections=True)}),
    Variant("element step", "0.25 mm", {"diffraction": Diffraction(step_m=2.5e-4)}),
    Variant("element step", "0.5 mm", {"diffraction": Diffraction(step_m=5e-4)}),
    Variant("element step", "2 mm", {"diffraction": Diffraction(step_m=2e-3)}),
    Variant("element step", "4 mm", {"diffraction": Diffraction(step_m=4e-3)}),
    Variant("live-bin margin", "0 bins", constants={LIVE: 0}),
    Variant("live-bin margin", "1 bin", constants={LIVE: 1}),
    Variant("live-bin margin", "4 bins", constants={LIVE: 4}),
    # the Doppler renderer takes sinc or lagrange: nearest only where nothing moves
    Variant("interpolator", "nearest", {"fractional_delay": "nearest"}, only=("shoebox",)),
    Variant("interpolator", "lagrange", {"fractional_delay": "lagrange"}),
    Variant("render rate", "baseband", {"render_rate": "baseband"}),
    Variant("Doppler nodes", "tol 1e-4", render={"doppler_tolerance": 1e-4}, only=MOVING),
    Variant("Doppler nodes", "tol 1e-2", render={"doppler_tolerance": 1e-2}, only=MOVING),
    Variant("gain sets", "tol 3e-4", render={"compress_tolerance": 3e-4}, only=MOVING),
    Variant("gain sets", "tol 3e-3", render={"compress_tolerance": 3e-3}, only=MOVING),
)
#: the knob settings of a --quick run
QUICK = {
    "500 rays",
    "1 bounce",
    "-60 dB",
    "order 1",
    "2 mm",
    "1 bin",
    "lagrange",
    "baseband",
    "tol 1e-2",
}
PRESETS = tuple(Variant("preset", q, quality=q) for q in ("fast", "default", "reference"))
#: the reference: the "reference" preset and the other knobs at their finest
REFERENCE = Variant(
    "reference",
    "reference",
    quality="reference",
    render={"doppler_tolerance": 1e-4, "compress_tolerance": 3e-4},
    constants={LIVE: 4},
)


@dataclass(frozen=True)
class Case:
    """A scene of the front and the poses it is measured at."""

    name: str
    scene: Scene
    poses: tuple[int, ...]


def cases(quick: bool) -> list[Case]:
    corridor = _quiet(load_scene(SCENES / "corridor.toml"))
    shoebox = _quiet(load_scene(SCENES / "shoebox.toml"))
    room = (
        Pose(np.array([0.0, 0.0, 0.0])),
        Pose(np.array([1.2, 0.5, 0.2]), yaw_rad=np.deg2rad(40)),
        Pose(np.array([-0.3, -0.8, 0.0]), yaw_rad=np.deg2rad(200)),
        Pose(np.array([2.0, 1.0, -0.3]), yaw_rad=np.deg2rad(-60), pitch_rad=0.2),
    )
    shoebox = dataclasses.replace(shoebox, sensor=dataclasses.replace(shoebox.sensor, poses=room))
    return [
        Case("corridor", corridor, (10, 40) if quick else (5, 20, 35, 50)),
        Case("shoebox", shoebox, (0, 1) if quick else (0, 1, 2, 3)),
    ]


def _quiet(scene: Scene) -> Scene:
    """No noise and no direct path: the simulation's error alone."""
    sim = dataclasses.replace(scene.simulation, snr_db=np.inf)
    sensor = dataclasses.replace(scene.sensor, direct_path=False)
    return dataclasses.replace(scene, simulation=sim, sensor=sensor)


def _scene(scene: Scene, v: Variant) -> Scene:
    sim = scene.simulation
    if v.quality is not None:
        sim = sim.with_quality(v.quality)
    changes = dict(v.simulation)
    if changes.get("bounces") == "+1":
        changes["bounces"] = sim.bounces + 1
    return dataclasses.replace(scene, simulation=dataclasses.replace(sim, **changes))


@contextlib.contextmanager
def _constants(values: Mapping[str, Any]) -> Iterator[None]:
    """Module constants set for the duration (restored after)."""
    old = {}
    try:
        for where, value in values.items():
            module, name = where.split(":")
            mod = importlib.import_module(module)
            old[where] = (mod, name, getattr(mod, name))
            setattr(mod, name, value)
        yield
    finally:
        for mod, name, value in old.values():
            setattr(mod, name, value)


@dataclass(frozen=True)
class Run:
    """A variant's recordings and its time per measurement (s)."""

    variant: Variant
    recordings: list[P.Recording]
    seconds: float
    #: the median of its pairs' time ratios to the defaults (None: timed alone)
    ratio: float | None = None


class Timed:
    """A variant's simulator, ready to run its case's poses (warmed up)."""

    def __init__(self, case: Case, v: Variant) -> None:
        self.case, self.variant = case, v
        self.times: list[float] = []  # of run(), when it is the defaults' timer
        with _constants(v.constants):
            self.sim = Simulator(_scene(case.scene, v))
            self.sim.options = dataclasses.replace(self.sim.options, **v.render)
            self.sim.run(case.poses[:1])  # warm-up: compiled kernels, caches

    def run(self) -> tuple[list[P.Recording], float]:
        """The recordings of every pose and the time per measurement (s), every
        trace paid."""
        with _constants(self.variant.constants):
            self.sim.tracer.forget()
            t = time.perf_counter()
            recs = self.sim.run(self.case.poses)
            return recs, (time.perf_counter() - t) / len(self.case.poses)


def measure(case: Case, v: Variant, rounds: int, default: Timed | None = None) -> Run:
    """`v` on `case`; with `default`, in `rounds` alternating pairs with it: the
    time is the default's median times the median of the pairs' ratios."""
    timed = Timed(case, v)
    times, ratios = [], []
    for _ in range(rounds):
        recs, t = timed.run()
        times.append(t)
        if default is not None:
            _, t0 = default.run()
            default.times.append(t0)
            ratios.append(t / t0)
    if default is None:
        return Run(v, recs, float(np.median(times)))
    ratio = float(np.median(ratios))
    return Run(v, recs, float(np.median(default.times)) * ratio, ratio)


def _db(num: float, den: float) -> float:
    return FLOOR_DB if num <= 0 else max(10 * np.log10(num / den), FLOOR_DB)


def das_images(recs: Sequence[P.Recording]) -> list[P.Image]:
    from acousim.imaging.run import ImagingOptions

    options = ImagingOptions(methods=("das",), energy_fraction=0.0, min_range_m=IMAGE_MIN_RANGE_M)
    return [P.acoustic_image(r, "das", options.settings(r)) for r in recs]


def _cells(img: P.Image, peaks: P.Peaks) -> np.ndarray:
    """(P, 3) cell indices (range, elevation, azimuth) of `peaks`."""
    axes = (img.range_m, img.elevation_rad, img.azimuth_rad)
    values = (peaks.range_m, peaks.elevation_rad, peaks.azimuth_rad)
    return np.stack(
        [np.argmin(np.abs(a[None, :] - v[:, None]), axis=1) for a, v in zip(axes, values)], axis=1
    ).reshape(-1, 3)


def peak_changes(ref: P.Image, img: P.Image) -> tuple[int, int]:
    """(lost, added): the reference's peaks within PEAK_DB of its strongest cell that
    `img` has not within one cell and 1 dB, and `img`'s that the reference has not
    within one cell."""
    low = PEAK_DB - PEAK_SLACK_DB
    pr, pi = ref.peaks(low), img.peaks(low)
    cr, ci = _cells(ref, pr), _cells(img, pi)
    near = np.all(np.abs(cr[:, None, :] - ci[None, :, :]) <= 1, axis=2)  # (R, I)
    close = near & (np.abs(pr.level_db[:, None] - pi.level_db[None, :]) <= PEAK_SLACK_DB)
    lost = int(np.sum((pr.level_db >= PEAK_DB) & ~close.any(axis=1)))
    added = int(np.sum((pi.level_db >= PEAK_DB) & ~near.any(axis=0)))
    return lost, added


@dataclass(frozen=True)
class Point:
    """A variant's place on the front."""

    variant: Variant
    ms: float
    waveform_db: float
    image_db: float
    lost: int
    added: int
    peaks: int  # the reference's peaks compared


def compare(ref: Run, ref_images: list[P.Image], run: Run) -> Point:
    num = sum(
        float(np.sum((a.samples - b.samples) ** 2)) for a, b in zip(run.recordings, ref.recordings)
    )
    den = sum(float(np.sum(b.samples**2)) for b in ref.recordings)
    images = das_images(run.recordings)
    inum = sum(float(np.sum((a.power - b.power) ** 2)) for a, b in zip(images, ref_images))
    iden = sum(float(np.sum(b.power**2)) for b in ref_images)
    changes = [peak_changes(r, i) for r, i in zip(ref_images, images)]
    n_peaks = sum(int(np.sum(r.peaks(PEAK_DB).level_db >= PEAK_DB)) for r in ref_images)
    return Point(
        run.variant,
        run.seconds * 1e3,
        _db(num, den),
        _db(inum, iden),
        sum(c[0] for c in changes),
        sum(c[1] for c in changes),
        n_peaks,
    )


#: a scene's reference point and its variants' points (what the picture draws)
Results = Mapping[str, tuple[Point, list[Point]]]
_NUMBERS = ("ms", "waveform_db", "image_db", "lost", "added", "peaks")
#: what a point's numbers are, said in the file
FIELDS = (
    "ms: time per measurement (ms); waveform_db, image_db: residual re the reference (dB; "
    "floor_db: none, identical output); lost, added: the reference's image peaks the run "
    "loses and the run's it adds, of peaks (over all poses); quality: the preset, or null"
)


def _point_dict(p: Point) -> dict[str, Any]:
    v = p.variant
    return {"knob": v.knob, "label": v.label, "quality": v.quality} | {
        k: getattr(p, k) for k in _NUMBERS
    }


def _point(d: Mapping[str, Any], where: str) -> Point:
    try:
        v = Variant(str(d["knob"]), str(d["label"]), quality=d.get("quality"))
        return Point(v, *(float(d[k]) if k.endswith(("ms", "db")) else int(d[k]) for k in _NUMBERS))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(
            f"{where}: a point needs knob, label, {', '.join(_NUMBERS)}: {exc!r}"
        ) from exc


def save(
    results: Results, path: Path = DATA, *, poses: Mapping[str, Sequence[int]], header: str
) -> None:
    """Write the front's points to `path` (JSON, atomically): per scene its poses, the
    reference's point and every variant's; times in ms, errors in dB (FLOOR_DB: none)."""
    from processing.base.atomic import write_text

    scenes = {
        name: {
            "poses": list(poses[name]),
            "reference": _point_dict(ref),
            "points": [_point_dict(p) for p in points],
        }
        for name, (ref, points) in results.items()
    }
    top = {"header": header, "fields": FIELDS, "floor_db": FLOOR_DB, "scenes": scenes}
    text = json.dumps(top, indent=1)
    # a point (and the poses) on one line: JSON strings hold no raw newline
    text = re.sub(r"\{[^{}\[\]]*\}|\[[^{}\[\]]*\]", lambda m: re.sub(r"\n\s*", " ", m[0]), text)
    write_text(path, text + "\n")


def load(path: Path = DATA) -> dict[str, tuple[Point, list[Point]]]:
    """The points :func:`save` wrote, by scene."""
    try:
        scenes = json.loads(Path(path).read_text())["scenes"]
        return {
            name: (
                _point(s["reference"], f"{path}: {name} reference"),
                [_point(d, f"{path}: {name} point {i}") for i, d in enumerate(s["points"])],
            )
            for name, s in scenes.items()
        }
    except (OSError, json.JSONDecodeError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(f"{path}: not a front file ({exc!r})") from exc


def redraw(data: Path = DATA, picture: Path = PICTURE) -> None:
    """Redraw the picture from the points a run kept, without measuring."""
    draw(load(data), picture)


def front(case: Case, quick: bool, log=print) -> tuple[Point, list[Point]]:
    """The reference's point and every variant's on `case`."""
    rounds = 1 if quick else 3
    ref = measure(case, REFERENCE, 1)
    log(f"  {case.name} reference: {ref.seconds * 1e3:.0f} ms")
    ref_images = das_images(ref.recordings)
    default = Timed(case, PRESETS[1])
    points: list[tuple[Point, float]] = []
    for v in (*PRESETS, *KNOBS):
        if v.only is not None and case.name not in v.only:
            continue
        if quick and v.quality is None and v.label not in QUICK:
            continue
        try:
            run = measure(case, v, rounds, default)
        except InputError as exc:  # a setting this scene refuses: said, not drawn
            log(f"  {case.name} {v.knob} {v.label}: refused ({exc})")
            continue
        p = compare(ref, ref_images, run)
        log(
            f"  {case.name} {v.knob} {v.label}: {p.ms:.0f} ms, waveform {p.waveform_db:.1f} dB, "
            f"image {p.image_db:.1f} dB, peaks lost {p.lost} added {p.added} of {p.peaks}"
        )
        assert run.ratio is not None  # timed in pairs with the defaults
        points.append((p, run.ratio))
    # every variant's time: its ratio times the defaults' median over the whole
    # section (the first variants' medians of a few runs would carry a load spike)
    final = float(np.median(default.times)) * 1e3
    return compare(ref, ref_images, ref), [dataclasses.replace(p, ms=final * r) for p, r in points]


def draw(results: Results, path: Path) -> None:
    """Draw the front (:mod:`benchmarks.front_picture`): time per measurement against
    the waveform and the image residual, a panel per scene and error."""
    from benchmarks.front_picture import draw as draw_front

    draw_front(results, path)


def _row(p: Point, default_ms: float) -> str:
    v = p.variant
    fmt = lambda x: "exact" if x <= FLOOR_DB else f"{x:.1f}"  # noqa: E731
    label = f"**{v.label}**" if v.quality else v.label
    return (
        f"| {v.knob} | {label} | {p.ms:.0f} | {default_ms / p.ms:.2f}x | {fmt(p.waveform_db)} | "
        f"{fmt(p.image_db)} | {p.lost} / {p.added} of {p.peaks} |"
    )


def _table(name: str, case: Case, ref: Point, points: list[Point]) -> list[str]:
    default = next(p for p in points if p.variant.quality == "default")
    return [
        f"### {name}: poses {', '.join(map(str, case.poses))}",
        "",
        f"The reference: {ref.ms:.0f} ms per measurement.",
        "",
        "| knob | setting | ms per measurement | speed re default | waveform residual (dB) | "
        "DAS image residual (dB) | peaks lost / added |",
        "|---|---|---|---|---|---|---|",
        *[_row(p, default.ms) for p in points],
        "",
    ]


def run(quick: bool = False, picture: Path = PICTURE, data: Path = DATA) -> str:
    """Measure the front (a full run keeps its points in `data`), draw `picture`, and
    return the section's text."""
    results, tables, poses = {}, [], {}
    for case in cases(quick):
        ref, points = front(case, quick)
        results[case.name] = (ref, points)
        poses[case.name] = case.poses
        tables += _table(case.name, case, ref, points)
    if not quick:
        import datetime

        when = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
        header = f"Measured by benchmarks/front.py (python -m benchmarks front) on {when}."
        save(results, data, poses=poses, header=header)
    draw(results, picture)
    return "\n".join(
        [
            "## Run time against error: every knob, the quality presets",
            "",
            "![run time against error](docs/front.png)",
            "",
            "Each knob set in turn from the scene's defaults, every other knob at the "
            "scene's own settings, and the three quality presets (`simulation.quality`); "
            "against a reference with every knob at its most accurate (the `reference` "
            "preset: 0.25 mm element step, the energy floor at -120 dB; the ray budget "
            "automatic; the Doppler renderer's tolerances 1e-4 and 3e-4; the live-bin "
            "margin 4; what the model includes, the bounces and the orders of "
            'diffraction, as the scene sets it: "file\'s + 1" and "+ reflections" '
            "show what more would add).  Noise off, the direct "
            "path left out.  Time: `Simulator.run` over the poses after a warm-up pose, "
            "every trace paid, per measurement (preparation apart), each point in 3 "
            "alternating pairs with the defaults: the defaults' median time times the "
            "median of the pairs' ratios.  "
            "Waveform residual: over all microphones and samples, dB re the "
            "reference's energy.  DAS image residual: the 2 degree power images from "
            "0.3 m, dB re the reference image.  Peaks: the reference's local maxima "
            "within 30 dB of its strongest cell that the run loses (none within one "
            "cell and 1 dB) and those the run adds, over all poses.  The corridor's "
            "waveform residual at any ray budget is that of its diffuse tail: a random "
            "sum of Lambert contributions that each ray set draws anew (its energy per "
            "range bin converges, not its waveform: see the corridor section).  "
            "On this shared machine (2 cores, loaded by other jobs) the time of a "
            "setting that changes nothing scatters by tens of percent (the shoebox's "
            "diffraction and live-bin knobs, which change nothing there): the times are "
            "rough, the "
            "errors exact.  The points are kept in benchmarks/data/front.json and the "
            "picture is drawn from them (`python -m benchmarks.front --redraw` redraws it "
            "without measuring); its grey band is the spread of the times of the settings "
            "whose errors equal the default's, this run's noise on time.",
            "",
            *tables,
        ]
    )


if __name__ == "__main__":
    # python -m benchmarks.front [--quick | --redraw]: this section alone, printed; a
    # quick run (2 poses, a setting or two per knob, no pairs) draws front-quick.png
    # here; --redraw redraws docs/front.png from benchmarks/data/front.json
    if "--redraw" in sys.argv[1:]:
        redraw()
        print(f"redrew {PICTURE} from {DATA}")
        sys.exit(0)
    quick = "--quick" in sys.argv[1:]
    from acousim.process import configure

    configure()
    print(run(quick, Path("front-quick.png") if quick else PICTURE))
