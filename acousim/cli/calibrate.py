"""``acousim calibrate``: fit a scene's materials to recordings of it.

Fit the reflection and diffuse fraction of a scene's materials (every material a mesh
uses, or --param) to recordings of the scene: trace once, render each group of paths
once, and fit the energy per range bin, direction and band by robust least squares.
Writes the scene file with only the fitted values changed, each with its uncertainty in
a comment, and prints the residual before and after per range bin and per parameter,
and warnings where the recordings do not determine a value (on a bound, a sigma wider
than its range, parameters that trade against each other or against the level, an
emulated or real recording's unknown level): printed, in --report and at the top of
the fitted scene (docs/compare.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from acousim.cli.common import (
    UsageError,
    add_command,
    from_start,
    load_scene,
    output_file,
    parse_indices,
    progress,
)
from acousim.cli.options import add_declared
from processing.base.errors import InputError

SETTINGS = "acousim.calibrate.options:CalibrationSettings"


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument("recordings", help="recording file (.h5), or 'rtisdev-sample'")
    p.add_argument("--scene", required=True, help="scene file (.toml) the recordings are of")
    p.add_argument(
        "--out",
        required=True,
        help="fitted scene file, not the --scene file (the files it names are pointed to "
        "from its folder); an existing file is replaced only if acousim calibrate wrote it",
    )
    p.add_argument(
        "--poses",
        help="scene pose of each recording: '0,12,24' or '0:5' (default: each recording's "
        "pose_index, else its position in the file)",
    )
    p.add_argument(
        "--sensor",
        metavar="NAME",
        help="a rig's scene: fit to the recordings of its sonar NAME, simulated alone at "
        "its firings (its mount fixed; --poses index its firings; default: each "
        "recording's firing)",
    )
    p.add_argument(
        "--param",
        help="free parameters, comma-separated: MATERIAL, MATERIAL.reflection or "
        "MATERIAL.diffuse (default: every material a mesh uses, both)",
    )
    p.add_argument(
        "--table",
        action="append",
        default=[],
        metavar="MATERIAL=F1,F2,...",
        help="fit MATERIAL as a table over frequency at these kHz (repeatable)",
    )
    add_declared(p, "--bands", SETTINGS, "bands")
    add_declared(p, "--min-range", SETTINGS, "min_range_m", note="the direct path lies nearer")
    add_declared(p, "--max-range", SETTINGS, "max_range_m", note="default: the scene's")
    add_declared(p, "--bin", SETTINGS, "bin_m")
    add_declared(p, "--loss-scale", SETTINGS, "loss_scale")
    add_declared(p, "--max-evaluations", SETTINGS, "max_evaluations")
    p.add_argument("--loss", help="robust loss: soft_l1 (default), huber, cauchy, arctan, linear")
    p.add_argument(
        "--fit-level",
        action="store_true",
        help="also fit one overall level (a real recording's unknown gain; with one "
        "bounce it trades against the reflections: the report names them)",
    )
    p.add_argument(
        "--no-align", action="store_true", help="do not shift the recordings onto the simulation"
    )
    p.add_argument(
        "--report",
        help="also write the report as JSON to this file (an existing file: only a "
        "report acousim calibrate wrote is replaced)",
    )


def _tables(items: list[str]) -> dict:
    out = {}
    for item in items:
        name, eq, values = item.partition("=")
        try:
            out[name.strip()] = tuple(float(v) for v in values.split(","))
        except ValueError:
            eq = ""
        if not eq or not name.strip():
            raise UsageError("expected MATERIAL=F1,F2,... (kHz)", key="--table", value=item)
    return out


def _settings(args: argparse.Namespace):
    from acousim.calibrate import CalibrationSettings

    given = {
        "bands": args.bands,
        "min_range_m": args.min_range,
        "max_range_m": args.max_range,
        "bin_m": args.bin,
        "loss_scale": args.loss_scale,
        "max_evaluations": args.max_evaluations,
        "loss": args.loss,
    }
    kw = {k: v for k, v in given.items() if v is not None}
    if args.param:
        kw["parameters"] = tuple(s.strip() for s in args.param.split(",") if s.strip())
    return CalibrationSettings(
        tables=_tables(args.table), fit_level=args.fit_level, align=not args.no_align, **kw
    )


def _firings(rig, name: str, recs: list) -> list[int]:
    """Each recording's pose in the scene of the rig's sonar `name` alone: its firing
    among the sonar's (a rig's recording's ``pose_index`` is its firing among all
    the rig's), else its place in the file."""
    k = [s.name for s in rig.sonars].index(name)
    own = [m.index for m in rig.measurements() if m.sonar == k]
    out = []
    for i, r in enumerate(recs):
        q = r.provenance.pose_index
        out.append(own.index(q) if q in own else i)
    return out


def _not_the_scene(scene: str, out: Path, report: Path | None) -> None:
    """UsageError when --out or --report would overwrite the scene file (or each
    other): the user's scene would be lost."""
    from acousim.bundled import resolve_scene

    source = Path(resolve_scene(scene))  # a bundled scene's name: its file
    if not source.is_file():
        return  # no such scene: loading it says so
    for option, path in (("--out", out), ("--report", report)):
        if path is not None and path.exists() and path.samefile(source):
            raise UsageError(
                f"{option} {str(path)!r} is the scene file --scene {scene!r}: writing the "
                "fitted scene there would lose the one given; name another file"
            )
    if report is not None and report.absolute() == out.absolute():
        raise UsageError(f"--report {str(report)!r} is the --out file; name another file")


def run(args: argparse.Namespace) -> int:
    from acousim.calibrate import calibrate, write_scene
    from acousim.compare.inputs import load_real_recordings, of_sensor
    from acousim.scene.rig import sonar_scene

    out, report = Path(args.out), Path(args.report) if args.report else None
    _not_the_scene(args.scene, out, report)
    out = output_file("--out", out, "scene")  # the folders made are removed on failure
    report = output_file("--report", report, "calibration") if report else None
    try:
        settings = _settings(args)
        rig_scene = load_scene(args.scene)
        scene = sonar_scene(rig_scene, args.sensor)  # a rig: the sonar alone, mount fixed
        recs = load_real_recordings(
            args.recordings, speed_of_sound_m_s=scene.environment.speed_of_sound_m_s
        )
        recs = of_sensor(recs, args.sensor, args.recordings)
        poses = parse_indices("--poses", args.poses)
        if poses is None and rig_scene.rig is not None:
            poses = _firings(rig_scene.rig, args.sensor, recs)
        cal = calibrate(scene, recs, poses, settings, progress=progress("calibrate", "pose"))
        if scene.source is None:
            raise UsageError("needs a scene file to write the fitted one from", key="--scene")
        write_scene(scene.source, out, cal)
        if report:
            from processing.base.atomic import write_text

            write_text(report, cal.to_json())
    except InputError as exc:
        raise UsageError(str(exc)) from None
    print(cal.summary())
    print(
        f"fitted scene written to {out}"
        + (f", report to {report}" if report else "")
        + f" {from_start()}"
    )
    return 0
