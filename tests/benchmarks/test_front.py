"""The front's kept points and their picture (benchmarks/front.py, front_picture.py):
redrawn from a small hand-written file, read back from the figure's artists. No timings
are measured here."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks import front
from benchmarks.front_picture import GROUP_GID, LABEL_GID, POINT_GID, figure
from processing.base.errors import InputError


def _p(knob, label, ms, wave, image, quality=None, lost=0, added=0):
    return dict(knob=knob, label=label, quality=quality, ms=ms, waveform_db=wave,
                image_db=image, lost=lost, added=added, peaks=10)  # fmt: skip


#: three presets; three settings with the default's errors at 9, 11 and 14 ms (the
#: noise band: 9-14 ms with the default's 10); two knob settings far apart; four settings
#: at one spot (a crowd)
POINTS = [
    _p("preset", "fast", 8.0, -40.0, -45.0, quality="fast"),
    _p("preset", "default", 10.0, -60.0, -70.0, quality="default"),
    _p("preset", "reference", 40.0, -140.0, -140.0, quality="reference"),
    _p("margin", "0 bins", 9.0, -60.0, -70.0),
    _p("margin", "1 bin", 11.0, -60.0, -70.0),
    _p("margin", "4 bins", 14.0, -60.05, -70.0),
    _p("rays", "500 rays", 5.0, -5.0, -8.0, lost=3, added=2),
    _p("rays", "16000 rays", 30.0, -4.0, -9.0, lost=3, added=1),
    *[_p("floor", f"-{d} dB", 20.0, -25.0, -30.0) for d in (50, 60, 70, 80)],
]


def _file(tmp_path: Path, points=POINTS) -> Path:
    ref = _p("reference", "reference", 50.0, -140.0, -140.0, quality="reference")
    scene = {"poses": [0, 1], "reference": ref, "points": points}
    path = tmp_path / "front.json"
    path.write_text(json.dumps({"header": "hand-written", "scenes": {"room": scene}}))
    return path


def test_redraw_writes_a_png(tmp_path):
    picture = tmp_path / "front.png"
    front.redraw(_file(tmp_path), picture)
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # written under a temporary name and renamed: nothing else left behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["front.json", "front.png"]


def test_every_point_drawn_once_per_panel(tmp_path):
    fig = figure(front.load(_file(tmp_path)))
    axes = [ax for ax in fig.axes if ax.get_lines()]
    assert len(axes) == 2  # waveform and image, one scene
    for ax in axes:
        points = [ln for ln in ax.get_lines() if ln.get_gid() == POINT_GID]
        assert len(points) == len(POINTS)
        assert all(len(ln.get_xdata()) == 1 for ln in points)
        # nothing else drawn as a line: no second reference time
        assert len(ax.get_lines()) == len(POINTS)
        stars = [ln for ln in points if ln.get_marker() == "*"]
        assert len(stars) == 3


def test_labels_do_not_overlap_and_the_crowd_is_listed(tmp_path):
    fig = figure(front.load(_file(tmp_path)))
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes[:2]:
        labels = [t for t in ax.texts if t.get_gid() == LABEL_GID]
        texts = {t.get_text() for t in labels}
        # presets and the lone settings each labelled; the crowd boxed under one letter
        assert {"fast", "default", "reference", "500 rays", "16000 rays"} <= texts
        assert not {"-50 dB", "-60 dB", "-70 dB", "-80 dB"} & texts
        boxes = [t.get_window_extent(renderer) for t in labels]
        area = ax.get_window_extent(renderer)
        for i, a in enumerate(boxes):
            assert area.x0 <= a.x0 and a.x1 <= area.x1 and area.y0 <= a.y0 and a.y1 <= area.y1
            for b in boxes[:i]:
                assert not a.overlaps(b), (a, b)
        assert [p for p in ax.patches if p.get_gid() == GROUP_GID]


def test_noise_band_spans_the_settings_with_the_defaults_errors(tmp_path):
    fig = figure(front.load(_file(tmp_path)))
    for ax in fig.axes[:2]:
        (band,) = [p for p in ax.patches if p.get_gid() == "front-noise"]
        shown = band.get_transform().transform(band.get_path().vertices)  # display px
        y = ax.transData.inverted().transform(shown)[:, 1]
        assert min(y) == pytest.approx(9.0) and max(y) == pytest.approx(14.0)
        assert "9-14 ms" in ax.get_title() and "4 settings" in ax.get_title()
        # the presets' times (8, 10 and 40 ms) are not all inside: no "choose by error"
        assert "choose here by error" not in ax.get_title()


def test_a_file_without_points_is_refused_by_name(tmp_path):
    path = tmp_path / "front.json"
    path.write_text(json.dumps({"scenes": {"room": {"reference": {}}}}))
    with pytest.raises(InputError, match="front.json"):
        front.load(path)


def test_save_then_load_gives_the_points_back(tmp_path):
    results = front.load(_file(tmp_path))
    again = tmp_path / "again.json"
    front.save(results, again, poses={"room": (0, 1)}, header="test")
    assert front.load(again) == results
    assert json.loads(again.read_text())["header"] == "test"


def _listed(ax) -> set[str]:
    """The settings the panel's lists name ("knob label")."""
    boxes = [a for a in ax.artists if a.get_gid() == GROUP_GID]
    lines = [t.get_text() for b in boxes for t in b.get_child().get_children()[1:]]
    return {line[2 : line.index(":")] for line in lines}


@pytest.mark.parametrize("room", [True, False])
def test_every_point_is_labelled_or_listed(tmp_path, monkeypatch, room):
    if not room:  # no place tried: every label falls back to a list
        monkeypatch.setattr("benchmarks.front_picture.RADII", ())
    fig = figure(front.load(_file(tmp_path)))
    every = {f"{p['knob']} {p['label']}" for p in POINTS}
    for ax in fig.axes[:2]:
        labels = {t.get_text() for t in ax.texts if t.get_gid() == LABEL_GID}
        labelled = {name for name in every if name.split(" ", 1)[1] in labels}
        assert labelled | _listed(ax) == every
        assert len(labelled) == (len(every) - 4 if room else 0)


def test_a_full_run_keeps_its_points_and_draws_from_them(tmp_path, monkeypatch):
    """run() (measurement replaced by the hand-written points) writes the file and
    the picture."""
    from types import SimpleNamespace

    results = front.load(_file(tmp_path))
    monkeypatch.setattr(front, "cases", lambda quick: [SimpleNamespace(name="room", poses=(0, 1))])
    monkeypatch.setattr(front, "front", lambda case, quick: results["room"])
    kept, picture = tmp_path / "kept.json", tmp_path / "kept.png"
    text = front.run(picture=picture, data=kept)
    assert front.load(kept) == results
    assert json.loads(kept.read_text())["scenes"]["room"]["poses"] == [0, 1]
    assert picture.read_bytes()[:4] == b"\x89PNG"
    assert "| margin | 0 bins | 9 |" in text
