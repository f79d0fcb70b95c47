import numpy as np
import pytest

import processing as P
from acousim.cli import main


def test_demo_writes_images_whose_peaks_are_the_reflectors(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "fan.png" in printed
    rec = P.load_recording(tmp_path / "demo_recording.h5")
    img = P.acoustic_image(
        rec,
        "music-fbss",
        P.ProcessingSettings(
            frequency_hz=31250.0, energy_fraction=0.02, grid=P.Grid.degrees(step=1.0)
        ),
    )
    truth = np.asarray(rec.metadata["reflectors"]["positions_m"])
    pk = img.peaks(-25)
    found = np.stack(
        [
            pk.range_m * np.cos(pk.elevation_rad) * np.cos(pk.azimuth_rad),
            pk.range_m * np.cos(pk.elevation_rad) * np.sin(pk.azimuth_rad),
            pk.range_m * np.sin(pk.elevation_rad),
        ],
        axis=1,
    )
    # the four near reflectors each have an image peak within 5 cm
    for t in truth[np.linalg.norm(truth, axis=1) < 2.0]:
        assert np.min(np.linalg.norm(found - t, axis=1)) < 0.05
    from matplotlib.image import imread

    fan = imread(tmp_path / "fan.png")
    assert fan.shape[0] > 200 and fan[..., :3].std() > 0.05  # not blank


def test_info_describes_a_file_and_refuses_garbage(tmp_path, capsys):
    rec = P.Recording(np.zeros((64, 300)), 500e3, P.paper_8x8(), P.paper_chirp())
    P.save_recording(tmp_path / "r.h5", rec)
    assert main(["info", str(tmp_path / "r.h5")]) == 0
    assert "paper_8x8 (64 mics)" in capsys.readouterr().out
    (tmp_path / "bad.h5").write_text("nope")
    assert main(["info", str(tmp_path / "bad.h5")]) == 2
    err = capsys.readouterr().err
    assert "bad.h5" in err and "not an HDF5" in err and len(err.strip().splitlines()) == 1


def test_unknown_command_exits_2():
    with pytest.raises(SystemExit) as exc:
        main(["frobnicate"])
    assert exc.value.code == 2
