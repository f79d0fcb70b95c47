"""The report's verdicts are computed from the CSV numbers: change a number, the
verdict changes.  The committed study's CSVs (docs/reproduction) are the input."""

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest

from acousim.experiments import paper_study, report
from acousim.experiments.paper_study import StudyConfig, load_results

COMMITTED = Path(__file__).resolve().parents[3] / "docs" / "reproduction"


@pytest.fixture
def study(tmp_path, monkeypatch):
    """A copy of the committed study; the two simulated numbers of the report (the
    strongest-bin frequency, DAS's beamwidth) fixed, as they are tested below."""
    out = tmp_path / "study"
    shutil.copytree(COMMITTED, out)
    monkeypatch.setattr(report, "strongest_bin_frequency_hz", lambda: 27343.75)
    monkeypatch.setattr(report, "das_beamwidth_deg", lambda f: 14.0)
    return out


def _edit(path: Path, match: dict, column: str, value: float) -> None:
    """Set `column` to `value` on the rows of CSV `path` whose columns equal `match`."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    hit = 0
    for r in rows:
        if all(float(r[k]) == v if k != "method" else r[k] == v for k, v in match.items()):
            r[column] = repr(value)
            hit += 1
    assert hit, match
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _verdict(out: Path, claim: str) -> str:
    rows = [r for r in report.headline(load_results(out)) if r.claim.startswith(claim)]
    assert len(rows) == 1, claim
    return rows[0].verdict


def test_plain_music_fig12_verdict_follows_the_counts(study):
    claim = "Fig. 12: plain MUSIC resolves fewer than five"
    assert _verdict(study, claim) == "Contradicts"
    for n in (2, 3, 4):
        _edit(
            study / "fig12_resolved_sources.csv",
            {"n_sources": n, "method": "music"},
            "resolved_mean",
            float(n),
        )
    assert _verdict(study, claim) == "Agrees (all resolved)"


def test_das_fig6_verdict_follows_the_values(study):
    claim = "Fig. 6: DAS angular resolution"
    assert _verdict(study, claim).startswith("(0°, 0°): Agrees")
    for snr in range(0, 21, 2):
        _edit(
            study / "fig06_07_resolution_vs_snr.csv",
            {"azimuth_deg": 0.0, "snr_db": snr, "method": "das"},
            "angular_sr_mean",
            0.1,
        )
    assert _verdict(study, claim).startswith("(0°, 0°): Differs (ours/paper = 2.50")


def test_stability_verdict_follows_the_curve(study):
    claim = "Fig. 6: Capon-FBSS at (60°, 60°)"
    assert _verdict(study, claim).startswith("Contradicts")
    for snr in range(0, 21, 2):
        _edit(
            study / "fig06_07_resolution_vs_snr.csv",
            {"azimuth_deg": 60.0, "snr_db": snr, "method": "capon-fbss"},
            "angular_sr_mean",
            0.0013,
        )
    assert _verdict(study, claim).startswith("Agrees")


def test_dynamic_range_and_spacing_verdicts(study):
    claim = "Fig. 12: dynamic range"
    assert _verdict(study, claim).count("Differs") == 2
    for m in ("capon-fbss", "music-fbss"):
        _edit(
            study / "fig12_resolved_sources.csv",
            {"n_sources": 1, "method": m},
            "dynamic_range_db",
            57.0,
        )
    assert _verdict(study, claim).count("Agrees") == 2
    claim = "Fig. 11: DAS separates"
    assert _verdict(study, claim).startswith("Agrees")  # 26 against 24, one 2° step
    _edit(
        study / "fig11_attenuation_vs_spacing.csv",
        {"spacing_deg": 26, "method": "das"},
        "attenuation_db_mean",
        1.0,
    )
    _edit(
        study / "fig11_attenuation_vs_spacing.csv",
        {"spacing_deg": 28, "method": "das"},
        "attenuation_db_mean",
        1.0,
    )
    assert _verdict(study, claim).startswith("Differs (by +6°")


def _as_before_the_sub_cell_metric(path: Path) -> None:
    """CSV `path` as the study wrote it before it counted failed and sub-cell trials
    (those columns left out)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    keep = [c for c in rows[0] if c not in ("failed", "sub_cell")]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def test_old_csvs_are_reported_as_predating_the_sub_cell_metric(study, tmp_path):
    """CSVs written before the sub-cell metric (no failed / sub_cell columns), three of
    whose means sit on one 0.25° cell at (0°, 0°): h², h in radians, every repetition
    alike (std 0), as the whole-cell metric gave."""
    for name in ("fig06_07_resolution_vs_snr.csv", "fig09_10_resolution_vs_snapshots.csv"):
        _as_before_the_sub_cell_metric(study / name)
    cell = float(np.deg2rad(0.25)) ** 2
    for snr in (14, 16, 18):
        where = {"azimuth_deg": 0, "elevation_deg": 0, "snr_db": snr, "method": "music-fbss"}
        _edit(study / "fig06_07_resolution_vs_snr.csv", where, "angular_sr_mean", cell)
        _edit(study / "fig06_07_resolution_vs_snr.csv", where, "angular_sr_std", 0.0)
    results = load_results(study)
    text = report.write_report(results, tmp_path / "R.md", study, "acousim reproduce").read_text()
    assert "## Provenance" in text and "3 of their means sit exactly at one cell" in text
    assert "not counted; these CSVs predate the count" in text
    assert "## Not reproduced" in text and "Fig. 5" in text and "Figs. 13-14" in text
    assert "| verdict |" in text and "Agrees." not in text


def test_failed_trials_are_counted_and_left_out(monkeypatch, tmp_path):
    """A trial that gives no number is counted, not averaged."""

    def fake(trial, step, setup):
        assert setup is cfg  # the sweep's trials are by the study's setup
        bad = trial.seed % 3 == 0
        value = (np.nan, np.nan, np.nan) if bad else (1.0, 2.0, float(trial.seed % 2))
        return {m: value for m in paper_study.PAPER_METHODS}

    monkeypatch.setattr(paper_study, "resolution_trial", fake)
    cfg = StudyConfig(repetitions=6, snrs_db=(0.0,), workers=1)
    seeds = [paper_study._seed(cfg, 6, 0, 0, rep) for rep in range(6)]
    stats = paper_study._resolution_sweep(
        cfg, (0.0,), lambda p, v, rep, seed: paper_study.Trial((p,), v, seed), key=6
    )
    r = stats[paper_study.POSITIONS[0], 0.0, "das"]
    bad = [s % 3 == 0 for s in seeds]
    assert r.failed == sum(bad)
    assert r.sub_cell == sum(s % 2 for s, b in zip(seeds, bad) if not b)
    if not all(bad):
        assert r.angular_sr_mean == 1.0 and r.range_m_mean == 2.0


def test_das_beamwidth_matches_the_array_factor():
    """An 8-element line at 5 mm: |sin(N psi / 2) / (N sin(psi / 2))|^2 with
    psi = k d sin(az) falls 3 dB at the width computed here (a closed form)."""
    from scipy.optimize import brentq

    from acousim.experiments.trials import C, das_beamwidth_deg

    f, d, n = 31250.0, 5e-3, 8
    k = 2 * np.pi * f / C

    def af(az):
        psi = k * d * np.sin(az)
        return (np.sin(n * psi / 2) / (n * np.sin(psi / 2))) ** 2 - 0.5

    exact = 2 * np.rad2deg(brentq(af, 1e-6, np.deg2rad(20)))
    assert das_beamwidth_deg(f) == pytest.approx(exact, rel=0.03)
