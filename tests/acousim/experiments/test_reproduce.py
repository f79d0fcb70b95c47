"""The quick reproduction of the paper's study, run through the command line, and the
orderings the paper reports, read back from the CSV files it wrote."""

import csv
from collections import defaultdict

import numpy as np
import pytest

from acousim.cli import main

SMOOTHED = ("capon-fbss", "music-fss", "music-fbss")


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    import contextlib
    import io

    out = tmp_path_factory.mktemp("study")
    report = out / "REPRODUCTION.md"
    said, progress = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(said), contextlib.redirect_stderr(progress):
        code = main(
            ["reproduce", "--quick", "--out", str(out), "--report", str(report), "--workers", "1"]
        )
    assert code == 0
    SAID["stdout"], SAID["stderr"] = said.getvalue(), progress.getvalue()
    return out, report


SAID: dict[str, str] = {}  # what the study's run printed


def test_the_study_says_where_it_is(study):
    """Not a terminal: a line on stderr as each figure is done, in order, and one
    final line for the five experiments; the result on stdout."""
    import re

    lines = SAID["stdout"].splitlines()
    said = SAID["stderr"].splitlines()
    figures = ["Figs. 3-4", "Figs. 6-7", "Figs. 9-10", "Fig. 11", "Fig. 12"]
    assert len(said) == 6, said
    for i, (line, fig) in enumerate(zip(said, figures)):
        stage = rf"reproduce: {fig} \(.*\) done in [\d.]+ s \([\d.]+ s from the start\), "
        assert re.fullmatch(stage + rf"experiments {i + 1}/5", line), line
    pattern = r"reproduce: 5/5 experiments in [\d.]+ s \(.*experiments/s\)"
    assert re.fullmatch(pattern, said[-1]), said[-1]
    assert lines[-1].startswith(f"figures and CSVs in {study[0]}, report ")


def test_ctrl_c_leaves_no_file_of_the_run(tmp_path):
    """Ctrl-C once the first figures are done (synchronised on the line that says
    so): no figure, CSV, report or temporary file is left, a folder the run made is
    removed, and a folder that was there keeps its own files alone."""
    from tests.acousim.cli.test_interrupt import leftovers, run_interrupted

    new = tmp_path / "new"
    there = tmp_path / "there"
    there.mkdir()
    (there / "notes.txt").write_text("mine")
    for out in (new, there):
        args = ["reproduce", "--quick", "--workers", "1", "--out", str(out)]
        code, lines = run_interrupted(args, tmp_path, after="experiments 1/5")
        assert code == 130, lines
        assert "no partial file was kept" in lines[-1]
        assert leftovers(tmp_path) == []
    assert not new.exists()
    assert [p.name for p in there.iterdir()] == ["notes.txt"]


def read(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_angular_resolution_orderings(study):
    out, _ = study
    rows = read(out / "fig06_07_resolution_vs_snr.csv")
    sr = defaultdict(list)
    for r in rows:
        if float(r["snr_db"]) >= 0:
            sr[float(r["azimuth_deg"]), r["method"]].append(float(r["angular_sr_mean"]))
    mean = {k: np.mean(v) for k, v in sr.items()}
    # DAS is about 0.04 sr at (0, 0) and about 0.12 sr at (60, 60)
    assert 0.03 < mean[0.0, "das"] < 0.06 and 0.09 < mean[60.0, "das"] < 0.15
    for az in (0.0, 30.0, 60.0):
        for m in SMOOTHED:
            assert mean[az, m] < mean[az, "das"] / 5, (az, m)
    # range resolution within about 6 cm everywhere
    assert max(float(r["range_m_mean"]) for r in rows) < 0.07


def test_snapshots_help_plain_music_not_das(study):
    out, _ = study
    rows = read(out / "fig09_10_resolution_vs_snapshots.csv")
    val = {
        (float(r["azimuth_deg"]), int(r["snapshots"]), r["method"]): float(r["angular_sr_mean"])
        for r in rows
    }
    assert val[60.0, 15, "music"] < val[60.0, 1, "music"] / 2
    assert val[60.0, 15, "das"] == pytest.approx(val[60.0, 1, "das"], rel=0.1)


def test_two_source_separation_limits(study):
    out, _ = study
    att = {
        (float(r["spacing_deg"]), r["method"]): float(r["attenuation_db_mean"])
        for r in read(out / "fig11_attenuation_vs_spacing.csv")
    }
    # the smoothed methods keep > 10 dB down to about 14 degrees
    for m in SMOOTHED:
        assert att[16.0, m] > 10, m
    # DAS separates (> 3 dB) at 30 degrees but not at 20 (paper: down to 24)
    assert att[30.0, "das"] > 3 and att[20.0, "das"] < 3
    # plain MUSIC never gets near the smoothed methods (paper: at most about 8 dB)
    assert max(v for (s, m), v in att.items() if m == "music") < 10


def test_four_coherent_sources_resolved_not_five(study):
    out, _ = study
    res = {
        (int(r["n_sources"]), r["method"]): float(r["resolved_mean"])
        for r in read(out / "fig12_resolved_sources.csv")
    }
    for m in ("capon-fbss", "music-fbss"):
        assert res[4, m] == 4.0 and res[5, m] < 5.0, m


def test_matched_filter_numbers_and_report(study):
    out, report = study
    mf = read(out / "fig04_matched_filter.csv")
    r = np.array([float(x["range_m"]) for x in mf])
    v = np.array([float(x["mf_normalised"]) for x in mf])
    assert r[np.argmax(np.abs(v))] == pytest.approx(1.0082, abs=2e-3)
    text = report.read_text()
    assert "| Fig. 12" in text and "1.003 m" in text
    for png in ["fig03_spectrogram.png", "fig06_angular_vs_snr.png", "fig12_multiple_sources.png"]:
        assert (out / png).stat().st_size > 10_000


def test_report_only_reads_back_the_same_statistics(study, tmp_path, capsys):
    import shutil

    from acousim.experiments import Attenuation, StudyResults, load_results

    out, report = study
    results = load_results(out)
    assert isinstance(results, StudyResults) and results.config.repetitions == 3
    assert isinstance(results.fig11[16.0, "das"], Attenuation)
    again = out / "again.md"  # beside the figures, as the first report
    assert main(["reproduce", "--report-only", "--out", str(out), "--report", str(again)]) == 0
    assert again.read_text() == report.read_text()  # the same numbers, read back
    broken = tmp_path / "broken"
    shutil.copytree(out, broken)
    (broken / "fig11_attenuation_vs_spacing.csv").write_text("spacing_deg,method\n10,das\n")
    capsys.readouterr()
    assert main(["reproduce", "--report-only", "--out", str(broken)]) == 2
    err = capsys.readouterr().err
    assert "fig11_attenuation_vs_spacing.csv: malformed study file" in err


def test_the_report_names_one_snr_once(study):
    """Where plain MUSIC fails at one SNR alone (the quick study) the report says "at
    -10 dB", never "at -10 to -10 dB"; several: "at -16 to -10 dB"."""
    import re

    from acousim.experiments.report import _snr_span

    assert _snr_span([-10.0]) == "-10 dB" and _snr_span([-10.0, -10.0]) == "-10 dB"
    assert _snr_span([-10.0, -16.0, -13.0]) == "-16 to -10 dB"
    text = study[1].read_text()
    for lo, hi in re.findall(r"Plain MUSIC at (-?\d+)(?: to (-?\d+))? dB", text):
        assert lo != hi


def test_stage_lines_keep_quiet_with_quiet(capsys, monkeypatch):
    """--quiet: no stage line; else one line on stderr (not a terminal), nothing on
    stdout."""
    from acousim.cli import common

    monkeypatch.delenv(common.PROGRESS_LINES, raising=False)
    bar = common.progress("reproduce", "experiment")
    try:
        common.set_quiet(True)
        bar.say("hidden")
    finally:
        common.set_quiet(False)
    bar.say("Fig. 11 done")
    said = capsys.readouterr()
    assert said.err == "reproduce: Fig. 11 done\n" and said.out == ""
