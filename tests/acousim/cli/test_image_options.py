"""``acousim image``'s grid span, steering frequency, MUSIC subspace size and
smoothing subarray: a point reflector at (45, 45) degrees on the paper's 8x8, out of
the default elevation span, is found where it is once the span covers it."""

from __future__ import annotations

import csv

import numpy as np
import pytest

import processing as P
from acousim.cli import build_parser, main
from acousim.synth import Noise, PointReflectors, simulate_points


@pytest.fixture(scope="module")
def point_45_45(tmp_path_factory):
    """One recording of the paper's 8x8 of a reflector at (45, 45) degrees, 1 m."""
    refl = PointReflectors.spherical(np.deg2rad([45.0]), np.deg2rad([45.0]), [1.0], 1.0)
    rec = simulate_points(
        refl,
        P.paper_8x8(),
        P.paper_chirp(),
        500e3,
        4096,
        spreading="paper",
        noise=Noise(snr_db=30.0, seed=5),
    )
    path = tmp_path_factory.mktemp("rec") / "point.h5"
    P.save_recordings(path, [rec])
    return path


def strongest(out) -> dict[str, str]:
    with open(out / "peaks.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["method"] == "das"]
    return max(rows, key=lambda r: float(r["level_db"]))


def image(path, out, *extra: str) -> dict[str, str]:
    args = ["image", str(path), "--out", str(out), "--method", "das", "--no-3d", *extra]
    assert main(args) == 0
    return strongest(out)


def test_a_wider_span_finds_the_point_where_it_is(point_45_45, tmp_path, capsys):
    """Default span (elevation -40..40): the peak sits on the edge, at 40 degrees;
    --elevation -60 60: within one 2 degree cell of (45, 45)."""
    edge = image(point_45_45, tmp_path / "default")
    assert float(edge["elevation_deg"]) == pytest.approx(40.0)
    assert edge["on_grid_edge"].lower() in ("true", "1")
    peak = image(point_45_45, tmp_path / "wide", "--elevation", "-60", "60")
    assert abs(float(peak["azimuth_deg"]) - 45.0) <= 2.0
    assert abs(float(peak["elevation_deg"]) - 45.0) <= 2.0
    assert peak["on_grid_edge"].lower() in ("false", "0")


def test_the_options_reach_the_processing_settings(point_45_45):
    from acousim.cli.image import _imaging_options

    args = build_parser().parse_args(
        ["image", str(point_45_45), "--azimuth", "0", "80", "--elevation", "-60", "60"]
        + ["--frequency-khz", "31.25", "--n-sources", "2", "--subarray", "4", "5"]
    )
    options = _imaging_options(args)
    settings = options.settings(P.load_recording(point_45_45, 0))
    assert settings.frequency_hz == 31250.0
    assert settings.n_sources == 2 and settings.subarray == (4, 5)
    assert np.rad2deg(settings.grid.elevation_rad[[0, -1]]) == pytest.approx([-60, 60])
    assert np.rad2deg(settings.grid.azimuth_rad[[0, -1]]) == pytest.approx([0, 80])


@pytest.mark.parametrize(
    "bad, option",
    [
        (["--elevation", "60", "-60"], "--elevation"),
        (["--azimuth", "-100", "0"], "--azimuth"),
        (["--subarray", "4.5", "5"], "--subarray"),
        (["--frequency-khz", "0"], "--frequency-khz"),
        (["--n-sources", "0"], "--n-sources"),
    ],
)
def test_bad_values_name_their_option(point_45_45, tmp_path, capsys, bad, option):
    try:
        code = main(["image", str(point_45_45), "--out", str(tmp_path), *bad])
    except SystemExit as exc:  # argparse's own usage error
        code = exc.code
    assert code == 2
    assert option in capsys.readouterr().err
