"""The steering frequency and the array checked where imaging starts: a frequency that
is not a positive number refused, a URA steered above its alias-free limit warned
about (its grating lobe where array theory puts it), one microphone refused."""

import warnings

import numpy as np
import pytest

import processing as P
from tests.oracles.analytic import echo_recording, plane_wave_snapshot

C = 343.0


def _ura4():
    return P.ura(4, 4, 4e-3, name="my4x4")


def test_a_grating_lobe_above_the_alias_free_limit_warns_and_lies_where_theory_puts_it():
    arr = _ura4()
    f, az0, el0 = 80e3, 30.0, 10.0
    # array theory: a(u) depends on u only through k (v dy, w dz) modulo 2 pi, with
    # v = cos(el) sin(az), w = sin(el); v shifted by c / (f dy) gives the same vector
    v0 = np.cos(np.deg2rad(el0)) * np.sin(np.deg2rad(az0))
    v1 = v0 - C / (f * 4e-3)
    az1 = np.rad2deg(np.arcsin(v1 / np.cos(np.deg2rad(el0))))
    assert -40 < az1 < -30  # inside the default grid's azimuths: a second, false echo
    grid = P.Grid(np.deg2rad(np.arange(-90, 90.001, 0.25)), np.deg2rad([el0]))
    x = plane_wave_snapshot(arr, az0, el0, f)[:, None]
    with pytest.warns(P.GratingLobeWarning) as caught:
        cut = P.doa_spectrum(x, arr, f, grid, "das")[0, 0]
    text = str(caught[0].message)
    assert "80000 Hz" in text and "42875 Hz" in text and "'my4x4'" in text
    assert f"cos(el) sin(az) differs by {v0 - v1:.3g}" in text  # 1.07: the shift above
    az = np.rad2deg(grid.azimuth_rad)
    # the two largest local maxima of the cut: the echo and its grating lobe
    inner = np.flatnonzero((cut[1:-1] >= cut[:-2]) & (cut[1:-1] >= cut[2:])) + 1
    top = inner[np.argsort(cut[inner])[-2:]]
    assert sorted(az[top]) == pytest.approx(sorted([az1, az0]), abs=0.25)
    assert cut[top].min() == pytest.approx(cut.max(), rel=1e-3)  # as strong as the echo


def test_the_default_frequency_stays_below_the_limit_without_a_warning():
    arr = _ura4()
    rec = echo_recording(arr, [(30, 10, 1.0, 1.0)], n_samples=4000, noise=1e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", P.GratingLobeWarning)
        img = P.acoustic_image(rec, "das", P.ProcessingSettings())
    assert img.frequency_hz <= C / (2 * 4e-3)


def test_an_irregular_array_never_warns():
    rng = np.random.default_rng(1)
    arr = P.from_coordinates(rng.uniform(-0.012, 0.012, (16, 2)), name="irr16")
    x = plane_wave_snapshot(arr, 30, 10, 80e3)[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("error", P.GratingLobeWarning)
        P.doa_spectrum(x, arr, 80e3, P.Grid.degrees(step=5.0), "das")


@pytest.mark.parametrize("bad", [np.nan, 0.0, -5.0, np.inf])
def test_a_frequency_that_is_not_positive_is_refused_by_every_entry(bad):
    arr = _ura4()
    grid = P.Grid.degrees(step=5.0)
    x = plane_wave_snapshot(arr, 0, 0, 30e3)[:, None]
    entries = [
        lambda: P.doa_spectrum(x, arr, bad, grid, "das"),
        lambda: P.doa_spectra(x, arr, bad, grid, ["das", "capon"]),
        lambda: P.steering_matrix(arr.positions_m, grid, bad, C),
        lambda: P.ProcessingSettings(frequency_hz=bad),
        lambda: P.stft_snapshot(np.ones((16, 600)), 450e3, frequency_hz=bad),
    ]
    for entry in entries:
        with pytest.raises(P.InputError, match=rf"frequency_hz = {bad!r}"):
            entry()


def test_a_steering_frequency_above_nyquist_is_refused():
    with pytest.raises(P.InputError, match=r"frequency_hz = 300000.0: above the Nyquist"):
        P.stft_snapshot(np.ones((16, 600)), 450e3, frequency_hz=300e3)


def test_one_microphone_cannot_image():
    one = P.from_coordinates(np.array([[0.0, 0.0]]), name="one")
    rec = echo_recording(one, [(30, 0, 1.0, 1.0)], n_samples=4000)
    want = r"array = 'one': imaging needs at least 2 microphones; this array has 1"
    for method in ["das", "capon", "music", "das-bb"]:
        with pytest.raises(P.InputError, match=want):
            P.acoustic_image(rec, method)
    with pytest.raises(P.InputError, match=want):
        P.doa_spectrum(np.ones((1, 3)), one, 30e3, P.Grid.degrees(), "das")
    with pytest.raises(P.InputError, match=want):
        P.energyscape(rec, P.Grid.degrees(step=10.0))


@pytest.mark.parametrize(
    "kw,meant",
    [
        ({"azimuth": (-1.57, 1.57)}, "(-90.0, 90.0)"),
        ({"azimuth": (0, 3.1416), "step": 0.1}, "(0.0, 180.0)"),
        ({"elevation": (-1.5708, 0.0), "step": 0.5}, "(-90.0, 0.0)"),
    ],
)
def test_radians_given_as_degrees_warn_with_what_was_meant(kw, meant):
    with pytest.warns(P.UnitsWarning, match=r"radians given as degrees\? In degrees") as got:
        P.Grid.degrees(**kw)
    assert meant in str(got[0].message)
    assert got[0].filename == __file__  # points at the caller's line


@pytest.mark.parametrize(
    "kw", [{}, {"azimuth": (-2, 2), "step": 0.1}, {"azimuth": (-1.5, 1.5), "step": 0.5}]
)
def test_grids_in_degrees_do_not_warn(kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error", P.UnitsWarning)
        P.Grid.degrees(**kw)


def test_a_non_finite_snapshot_is_named_by_microphone_and_range_bin():
    d = np.ones((16, 3), complex)
    d[2, 1] = np.nan
    want = r"^snapshots = \(nan\+0j\): non-finite snapshot at microphone 2, range bin 1$"
    with pytest.raises(P.InputError, match=want):
        P.doa_spectrum(d, _ura4(), 30e3, P.Grid.degrees(step=5.0), "das")
