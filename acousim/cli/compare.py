"""``acousim compare``: compare a real recording with its simulation.

Put a real recording beside its simulation (from a scene and pose, or an existing
simulated file): align the emission and the gain, compare matched-filter envelopes,
range profiles and images, match their peaks (a weaker peak within one STFT window of a
stronger one is reported as its side lobe; a matched echo is a real peak 10 dB above
the real noise floor paired with a traced simulated one), and write a JSON report and
a picture (docs/compare.md).
"""

from __future__ import annotations

import argparse

from acousim.cli.common import (
    INDEX,
    UsageError,
    add_command,
    choice,
    from_start,
    load_scene,
    methods,
    preload_simulation,
    progress,
    replaceable_in,
    writable_dir,
)
from acousim.cli.image import CHIRP_CALLS
from acousim.cli.record import add_array
from processing.base.errors import InputError


def register(sub) -> None:
    p = add_command(sub, __doc__, run)
    p.add_argument(
        "real",
        help="real recording: .h5 (ours, or a CHIRP file), raw tick words (.bin), or "
        "'rtisdev-sample' (the eRTIS sample of the rtisdev wheel)",
    )
    p.add_argument("--index", type=INDEX, default=0, help="recording in an .h5 file")
    p.add_argument("--scene", help="scene file (or a bundled scene's name) to simulate at --pose")
    p.add_argument(
        "--pose",
        type=INDEX,
        default=None,
        help="pose index in the scene (default: 0; for a CHIRP file with odometry, each "
        "recording's own pose)",
    )
    p.add_argument(
        "--sensor",
        metavar="NAME",
        help="a rig: its sonar NAME (the scene simulates its firings, --pose i its i-th, "
        "with the other sonars' calls that reach it when the rig's crosstalk is on; of "
        "a rig's real or --sim file, only its recordings)",
    )
    p.add_argument("--sim", help="an existing simulated recording file (.h5)")
    p.add_argument("--sim-index", type=INDEX, default=0, help="recording in the --sim file")
    p.add_argument(
        "--all",
        action="store_true",
        help="a trajectory: compare recording i with pose i (or --sim recording i)"
        " for every i; one row per pose and a summary in summary.json",
    )
    add_array(p, "array of a raw .bin")
    p.add_argument(
        "--call",
        default=None,
        type=choice("call", CHIRP_CALLS),
        help=f"call of a raw .bin (default: default_25_50), or of a CHIRP file that does not "
        f"say it: {', '.join(CHIRP_CALLS)}",
    )
    p.add_argument(
        "--method", default="das", help="comma-separated methods (as for image; e.g. das,das-bb)"
    )
    p.add_argument(
        "--out",
        help="folder for comparison.json and comparison.png (summary.json and a folder per "
        "pose with --all); default: nothing is written, the report is printed; a file "
        "there by those names that is not of its kind (a report of ours; the picture: any "
        "PNG) is never overwritten",
    )


def _pairs(args: argparse.Namespace):
    """The (real, simulated) recordings to compare, as the arguments ask."""
    import processing as P
    from acousim.compare.inputs import (
        load_real_recordings,
        of_sensor,
        pair_with_file,
        pair_with_rig,
        pair_with_scene,
    )
    from acousim.scene.rig import sonar_scene

    if args.scene:
        whole = load_scene(args.scene)
        scene = sonar_scene(whole, args.sensor)  # a rig: its sonar's poses
        c = scene.environment.speed_of_sound_m_s
    else:
        try:
            sims = of_sensor(P.load_recordings(args.sim), args.sensor, "--sim")
        except P.RecordingFileError as exc:
            raise UsageError(f"--sim {args.sim}: {exc}") from None
        if not sims:
            raise UsageError(f"--sim {args.sim}: the file holds no recording")
        c = sims[0].speed_of_sound_m_s
    reals = load_real_recordings(args.real, array=args.array, call=args.call, speed_of_sound_m_s=c)
    reals = of_sensor(reals, args.sensor, "the real file")
    if args.scene:
        preload_simulation()  # it simulates: the process's policy set
        recorded = (
            args.pose is None and P.is_chirp(args.real) and all("pose" in r.metadata for r in reals)
        )
        if whole.rig is not None and whole.rig.crosstalk and not recorded:
            return pair_with_rig(  # the other sonars' calls heard, as the rig fires
                reals,
                whole,
                args.sensor,
                every=args.all,
                index=args.index,
                pose=args.pose or 0,
                progress=progress("simulate", "pose"),
            )
        return pair_with_scene(
            reals,
            scene,
            every=args.all,
            index=args.index,
            pose=args.pose or 0,
            recorded=recorded,
            progress=progress("simulate", "pose"),
        )
    return pair_with_file(reals, sims, every=args.all, index=args.index, sim_index=args.sim_index)


def _pair_name(args: argparse.Namespace, n: int, count: int) -> str:
    """Which files pair `n` (of `count`) compares, for an error."""
    every = args.all and count > 1
    real = f"{args.real} recording {n if every else args.index}"
    if args.scene:
        sim = f"the scene {args.scene} at pose {n if every else (args.pose or 0)}"
    else:
        sim = f"--sim {args.sim} recording {n if every else args.sim_index}"
    return f"pair {n} (real: {real}; simulated: {sim})"


#: the files compare writes in its folder (and in each pose's, pose_NNNN, with --all)
WRITTEN = {
    "comparison.json": "comparison",
    "comparison.png": "picture",
    "summary.json": "summary",
}


def _replaced(out) -> dict[str, str]:
    """The files of ours a run may replace in `out` (:data:`WRITTEN`), with each
    pose folder's (their kinds: :data:`acousim.cli.ours.KINDS`)."""
    poses = sorted(p.name for p in out.glob("pose_*") if p.is_dir())
    return {**WRITTEN, **{f"{d}/{n}": k for d in poses for n, k in WRITTEN.items()}}


def run(args: argparse.Namespace) -> int:
    from acousim.compare.comparison import check_comparable, compare, write_comparison
    from acousim.compare.summary import summarize, write_summary
    from processing.base.atomic import committed_together

    if (args.scene is None) == (args.sim is None):
        raise UsageError("give exactly one of --scene SCENE or --sim SIM")
    out = writable_dir(args.out) if args.out else None  # nothing written unasked
    if out is not None:  # made now, removed again if the run fails
        replaceable_in("--out", out, _replaced(out))
    names = methods("--method", args.method)
    files: list = []
    with committed_together():  # every file or none (Ctrl-C, an error)
        try:
            pairs = _pairs(args)
            for n, (real, sim) in enumerate(pairs):
                try:
                    check_comparable(real, sim)
                except InputError as exc:
                    raise UsageError(f"{_pair_name(args, n, len(pairs))}: {exc}") from None
            reports = []
            step = progress("compare", "pair")
            for n, (real, sim) in enumerate(pairs):
                step(n, len(pairs))  # a Ctrl-C checkpoint
                try:
                    report, arrays = compare(real, sim, names)
                except InputError as exc:
                    raise UsageError(f"{_pair_name(args, n, len(pairs))}: {exc}") from None
                reports.append(report)
                if out is not None:
                    folder = out if len(pairs) == 1 else out / f"pose_{n:04d}"
                    files = write_comparison(report, arrays, folder)
            step(len(pairs), len(pairs))
        except InputError as exc:
            raise UsageError(str(exc)) from None
        if len(reports) > 1:
            s = summarize(reports)
            files = [write_summary(s, out)] if out is not None else []
    if len(reports) > 1:
        print(
            f"{s.poses} poses: mean envelope correlation {s.mean_envelope_correlation:.2f}, "
            f"{s.matched_echoes} matched echoes (median |d_range| {s.median_abs_d_range_m}, "
            f"median |d_azimuth| {s.median_abs_d_azimuth_deg}); the emission time and the "
            "gain are fitted to each pose"
        )
    else:
        _print_report(reports[0], arrays)
    for f in files:
        print(f"  {f}")
    if out is None:
        print("  (nothing written: --out FOLDER writes the JSON report and the picture)")
    print(from_start())
    return 0


def _echo_lines(m: str, r) -> list[str]:
    """The matched echoes of method `m` (:class:`MethodComparison` `r`), one line
    each, and what was paired but is not an echo both have."""
    from acousim.compare.comparison import MIN_ECHO_ABOVE_FLOOR_DB as need

    def where(p) -> str:
        return f"{p.range_m:.3f} m az {p.azimuth_deg:+.0f}° el {p.elevation_deg:+.0f}°"

    out = [
        f"  {m} echo {k}: real {where(p.real)} ({p.real_above_floor_db:+.1f} dB above the "
        f"real noise floor), sim {where(p.sim)}"
        + (f" (traced: {p.sim_truth_kind})" if p.sim_truth_kind else "")
        + f" (d_range {p.d_range_m * 100:+.1f} cm, d_level {p.d_level_db:+.1f} dB)"
        for k, p in enumerate(r.matched)
    ]
    if not r.real_max_above_floor_db >= need:
        top = r.real_max_above_floor_db
        most = f"its peaks stand at most {top:+.1f} dB above it" if top == top else "no peak"
        out.append(
            f"  {m}: no echo above the noise floor in the real recording ({most}; an echo "
            f"needs {need:g} dB)"
        )
    low = sum(x.reason == "real under the noise floor" for x in r.rejected)
    parts = [
        f"{low} with the real peak less than {need:g} dB above the noise floor" if low else "",
        f"{len(r.rejected) - low} where the simulation traced no path (a side lobe)"
        if len(r.rejected) > low
        else "",
    ]
    if r.rejected:
        out.append(
            f"  {m}: {len(r.rejected)} paired peak(s) not counted as echoes: "
            + ", ".join(x for x in parts if x)
        )
    if not r.sim_has_truth:
        out.append(
            f"  {m}: the simulated recording has no ground truth: its peaks are not "
            "checked against traced paths"
        )
    return out


def _print_report(report, arrays) -> None:
    from acousim.compare.account import account

    if report.span is not None:
        print(report.span.describe())
    print(f"mean envelope correlation {report.mean_envelope_correlation:.2f}")
    for m, r in report.images.items():
        for line in _echo_lines(m, r):
            print(line)
        print(
            f"  {m}: {len(r.side_lobes_real)} side lobe(s) in the real image, "
            f"{len(r.side_lobes_sim)} in the simulation; {len(r.only_real)} peak(s) only "
            f"in the real image ({r.only_real_above_floor} above the noise floor), "
            f"{len(r.only_sim)} only in the simulation"
        )
    for line in account(report, arrays).lines():
        print(line)
