"""The ``acousim`` command line: a thin layer that parses, calls the library, reports.

Errors in what the user gave (a file, a key, a value) are reported on one line with
exit code 2.
"""

from __future__ import annotations

import argparse
import sys
import time


class UsageError(Exception):
    """Bad input from the user: printed on one line, exit code 2."""


def _cmd_demo(args: argparse.Namespace) -> int:
    from acousim.demo import run_demo

    t0 = time.perf_counter()
    files = run_demo(args.out, seed=args.seed)
    print(f"demo written in {time.perf_counter() - t0:.1f} s:")
    for f in files:
        print(f"  {f}")
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from acousim.experiments import StudyConfig, run_study
    from acousim.experiments.report import write_report

    config = StudyConfig.quick(args.workers) if args.quick else StudyConfig(workers=args.workers)
    t0 = time.perf_counter()
    results = run_study(config, args.out, progress=lambda s: print(f"running {s} ...", flush=True))
    command = "acousim reproduce" + (" --quick" if args.quick else "")
    report = write_report(results, args.report, args.out, command)
    print(f"figures and CSVs in {args.out}, report {report} ({time.perf_counter() - t0:.0f} s)")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    import processing as P

    try:
        recs = P.load_recordings(args.file)
    except P.RecordingFileError as exc:
        raise UsageError(str(exc)) from None
    print(f"{args.file}: {len(recs)} recording(s)")
    for i, r in enumerate(recs):
        kind = "simulated" if r.metadata.get("simulated") else "real"
        print(
            f"  [{i}] {kind}, array {r.array.name} ({r.array.n_mics} mics), "
            f"{r.n_measurements} measurement(s) x {r.n_samples} samples at "
            f"{r.sample_rate_hz / 1e3:g} kHz, call {r.waveform.kind} "
            f"{r.waveform.f_start_hz / 1e3:g}->{r.waveform.f_end_hz / 1e3:g} kHz, "
            f"c = {r.speed_of_sound_m_s:g} m/s"
        )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="acousim",
        description="Simulate active in-air ultrasonic 3D sonars and image their recordings.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser(
        "demo",
        help="simulate the default scenario and write its images",
        description="Simulate the paper's point-reflector scenario, image it "
        "with every DOA method and write the pictures.",
    )
    p.add_argument("--out", default="out", help="output folder (default: out)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default: 0)")
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser(
        "reproduce",
        help="reproduce the paper's simulation study",
        description="Run the paper's section IV experiments (Figs. 3-12), "
        "write a CSV and a PNG per figure and regenerate the "
        "report that puts the paper's numbers beside ours.",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="3 repetitions, few SNRs/snapshots, 0.5 degree grid (about a minute)",
    )
    p.add_argument("--out", default="docs/reproduction", help="folder for figures and CSVs")
    p.add_argument("--report", default="docs/REPRODUCTION.md", help="report to (re)write")
    p.add_argument("--workers", type=int, default=2, help="processes (default: 2)")
    p.set_defaults(func=_cmd_reproduce)

    p = sub.add_parser(
        "info",
        help="describe what a recording file holds",
        description="Print what a recording file (HDF5) holds.",
    )
    p.add_argument("file", help="recording file (.h5)")
    p.set_defaults(func=_cmd_info)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except UsageError as exc:
        print(f"acousim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"acousim {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
