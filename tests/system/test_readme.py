"""The README's "Processing in five lines" runs, and finds the echo, with the one
set of defaults that the library and the command line share."""

import re

import numpy as np

import processing as P
from tests import REPO
from tests.oracles.analytic import echo_recording

README = REPO / "README.md"


def _five_lines() -> str:
    text = README.read_text()
    section = text[text.index("## Processing in five lines") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_readme_processing_example_finds_the_echo(tmp_path, monkeypatch, capsys):
    # a strong near "echo" at 5 cm stands for the emitter-to-microphone crosstalk of a
    # real or simulated recording; the reflector is at 1.2 m, azimuth 30, elevation -10
    rec = echo_recording(
        P.paper_8x8(), [(0, 0, 0.05, 30.0), (30, -10, 1.2, 1.0)], n_samples=4096, noise=1e-3
    )
    P.save_recording(tmp_path / "corridor.h5", rec)  # the name the README reads
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(_five_lines(), scope)
    images = scope["images"]
    pk = images["capon-fbss"].peaks(threshold_db=-10)
    assert np.all(pk.range_m >= 0.25)  # the crosstalk is not imaged
    best = np.argmax(pk.level_db)
    assert abs(pk.range_m[best] - 1.2) < 0.05
    assert abs(np.rad2deg(pk.azimuth_rad[best]) - 30) <= 2
    assert abs(np.rad2deg(pk.elevation_rad[best]) + 10) <= 2
    assert "Peaks" in capsys.readouterr().out


def test_command_line_defaults_are_the_library_defaults():
    from acousim.cli import build_parser
    from acousim.imaging.run import ImagingOptions

    s = P.ProcessingSettings()
    assert ImagingOptions().energy_fraction == s.energy_fraction
    assert ImagingOptions().min_range_m == s.range_limits_m[0]
    parser = build_parser()
    image = parser._subparsers._group_actions[0].choices["image"]
    # unset options are None: the declared default applies, and --help prints it
    args = parser.parse_args(["image", "x.h5"])
    assert args.energy_fraction is None and args.min_range is None
    text = " ".join(image.format_help().split())
    assert s.energy_fraction == 1e-3 and "[0, 1], default 0.001" in text
    assert f"[0, 1000], default {s.range_limits_m[0]!r}" in text
