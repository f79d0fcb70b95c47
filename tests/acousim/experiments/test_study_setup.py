"""The study beyond the paper's setup: another array, other methods, another steering
frequency, given to :class:`acousim.experiments.StudyConfig` and ``acousim reproduce``.
The μRTIS's DAS resolution at broadside is held to the closed-form beam of its 5 x 6
grid, written here."""

from __future__ import annotations

import numpy as np
import pytest

import processing as P
from acousim.cli import main
from acousim.experiments import StudyConfig, run_study
from processing.base.api import KeywordError
from processing.base.errors import InputError

C = 343.0


def dirichlet(n: int, x: np.ndarray) -> np.ndarray:
    """|sum_{i<n} exp(j i x)|^2 / n^2: the power pattern of n equally spaced elements."""
    den = n * np.sin(x / 2)
    safe = np.where(np.abs(den) < 1e-12, 1.0, den)
    return np.where(np.abs(den) < 1e-12, 1.0, (np.sin(n * x / 2) / safe) ** 2)


def ura_beam_solid_angle(n_rows: int, n_cols: int, pitch_m: float, frequency_hz: float) -> float:
    """-3 dB solid angle (sr) of a URA's delay-and-sum beam steered to broadside:
    the product of two Dirichlet kernels in v = sin(az) cos(el) and w = sin(el),
    integrated (cos(el) d az d el) over its main lobe on a 0.05 degree grid."""
    k = 2 * np.pi * frequency_hz / C
    step = np.deg2rad(0.05)
    ang = np.arange(-np.pi / 3, np.pi / 3, step)
    el, az = ang[:, None], ang[None, :]
    power = dirichlet(n_cols, k * pitch_m * np.sin(az) * np.cos(el)) * dirichlet(
        n_rows, k * pitch_m * np.sin(el)
    )
    # the side lobes of a 5 x 6 grid are 13 dB down: above half power is the main lobe
    return float(np.sum((power >= 0.5) * np.cos(el)) * step * step)


def test_the_setup_is_declared_and_misspellings_are_answered():
    cfg = StudyConfig()
    assert (cfg.array, cfg.sample_rate_hz, cfg.frequency_hz) == ("paper_8x8", 500e3, 31250.0)
    assert cfg.methods == ("das", "capon-fbss", "music", "music-fss", "music-fbss")
    with pytest.raises(KeywordError, match="did you mean 'array'"):
        StudyConfig(arrays="urtis_v1")
    with pytest.raises(KeywordError, match="did you mean 'methods'"):
        StudyConfig.quick(method=("das",))
    with pytest.raises(InputError, match="did you mean 'urtis_v1'"):
        StudyConfig(array="urtis")
    with pytest.raises(InputError, match="did you mean 'music'"):
        StudyConfig(methods=("das", "musik"))
    with pytest.raises(InputError, match="frequency_hz"):
        StudyConfig(frequency_hz=-1.0)


def exit_code(args: list[str]) -> int:
    """main's code, or argparse's (a usage error it found itself)."""
    try:
        return main(args)
    except SystemExit as exc:
        return int(exc.code)


def test_the_command_line_checks_the_setup(tmp_path, capsys):
    out = str(tmp_path / "o")
    assert exit_code(["reproduce", "--quick", "--out", out, "--array", "urtis"]) == 2
    assert "did you mean 'urtis_v1'" in capsys.readouterr().err
    assert exit_code(["reproduce", "--quick", "--out", out, "--method", "das,musik"]) == 2
    assert "did you mean 'music'" in capsys.readouterr().err
    assert exit_code(["reproduce", "--quick", "--out", out, "--frequency-khz", "0"]) == 2
    assert "--frequency-khz" in capsys.readouterr().err
    args = ["reproduce", "--report-only", "--out", out, "--array", "urtis_v1"]
    assert exit_code(args) == 2
    assert "--array" in capsys.readouterr().err


def test_the_parsers_paper_methods_are_the_studys():
    from acousim.cli.reproduce import PAPER_METHODS
    from acousim.experiments.trials import PAPER_METHODS as TRIALS

    assert PAPER_METHODS == TRIALS


def test_urtis_study_with_two_methods_matches_its_closed_form_beam(tmp_path):
    """A quick study of the μRTIS (5 rows x 6 columns at 3.85 mm) with DAS and
    MUSIC-FBSS: DAS's -3 dB solid angle at broadside is the closed-form beam's within
    3 % (0.3 % measured: the 0.5 degree grid, the STFT bin's width, the noise),
    MUSIC's far below it."""
    array = P.urtis_v1()
    y, z = array.positions_m[:, 1], array.positions_m[:, 2]
    assert (np.unique(y.round(6)).size, np.unique(z.round(6)).size, y.size) == (6, 5, 30)
    assert np.diff(np.unique(y.round(6))) == pytest.approx(3.85e-3)
    assert np.diff(np.unique(z.round(6))) == pytest.approx(3.85e-3)
    config = StudyConfig.quick(1, array="urtis_v1", methods=("das", "music-fbss"))
    results = run_study(config, tmp_path)
    broadside = (0.0, 0.0, 1.0)
    das = [results.fig6_7[broadside, snr, "das"].angular_sr_mean for snr in (10.0, 20.0)]
    reference = ura_beam_solid_angle(5, 6, 3.85e-3, 31250.0)
    assert 0.1 < reference < 0.3  # about (0.89 lambda / aperture)^2 pi / 4 sr
    assert np.mean(das) == pytest.approx(reference, rel=0.03)
    music = results.fig6_7[broadside, 20.0, "music-fbss"].angular_sr_mean
    assert music < reference / 10
    assert {m for *_, m in results.fig11} == {"das", "music-fbss"}
    assert (tmp_path / "fig12_multiple_sources.png").stat().st_size > 10_000


def test_the_azimuth_cut_takes_its_methods():
    """A trial images by the methods it is given: DAS's cut peaks at the source."""
    from acousim.experiments.trials import Trial, azimuth_cut_trial

    config = StudyConfig(array="urtis_v1", frequency_hz=25e3)
    cuts = azimuth_cut_trial(Trial(((20.0, 0.0, 1.0),), 30.0, 1), 1.0, config, methods=["das"])
    assert list(cuts) == ["das"]
    az = np.arange(-90, 90.5, 1.0)
    assert az[np.argmax(cuts["das"])] == pytest.approx(20.0, abs=1.0)


def test_the_fine_grid_remeasure_images_by_the_trials_setup_and_method(monkeypatch):
    """A lobe narrower than the grid step is measured again on a fine grid: every
    image of the trial, the re-measure's included, is by the trial's array, steering
    frequency and method (not the paper's), and the lobe it finds is below one cell."""
    from acousim.experiments import trials

    config = StudyConfig(array="urtis_v1", methods=("music-fbss",), frequency_hz=25e3)
    simulated, calls = [], []
    real_simulate, real_images = trials.simulate_trial, trials.P.acoustic_images

    def simulate(trial, setup=trials.PAPER):
        simulated.append(setup)
        return real_simulate(trial, setup)

    def spy(recording, methods, settings, **kw):
        size = settings.grid.azimuth_rad.size * settings.grid.elevation_rad.size
        calls.append((recording.array.n_mics, tuple(methods), settings.frequency_hz, size))
        return real_images(recording, methods, settings, **kw)

    monkeypatch.setattr(trials, "simulate_trial", simulate)
    monkeypatch.setattr(trials.P, "acoustic_images", spy)
    step = 5.0  # MUSIC-FBSS of the μRTIS at 30 dB: a lobe well inside one 5° cell
    out = trials.resolution_trial(trials.Trial(((0.0, 0.0, 1.0),), 30.0, 1), step, config)
    sr, range_m, sub_cell = out["music-fbss"]
    assert list(out) == ["music-fbss"] and sub_cell == 1.0
    assert len(calls) > 1  # the coarse image, then the fine grid's
    assert all(setup is config for setup in simulated)
    assert len(simulated) == 2  # the coarse image's, then once for every fine grid
    n_mics = trials.P.preset("urtis_v1").n_mics
    assert all(c[:3] == (n_mics, ("music-fbss",), 25e3) for c in calls)
    assert 0 < sr < np.deg2rad(step) ** 2 and 0 < range_m < 0.2
