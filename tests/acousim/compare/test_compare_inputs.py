"""``acousim compare`` on bad input: one line naming the file, and no --out folder
made before the inputs are read and checked."""

from __future__ import annotations

import numpy as np
import pytest

import processing as P
from acousim.cli import main


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


@pytest.mark.parametrize(
    "name, content, said",
    [
        ("gone.h5", None, "no such file"),
        ("text.h5", b"a text file", "not an HDF5 file"),
        ("odd.bin", bytes(1001), "1001 bytes, not a raw RTIS measurement"),
        ("short.bin", bytes(4000), "4000 bytes = 1000 tick words, not a raw RTIS measurement"),
    ],
)
def test_a_missing_or_broken_input_makes_no_folder(tmp_path, capsys, name, content, said):
    real = tmp_path / name
    if content is not None:
        real.write_bytes(content)
    out = tmp_path / "newdir" / "sub"
    assert main(["compare", str(real), "--scene", "wall", "--out", str(out)]) == 2
    err = _err(capsys)
    assert str(real) in err and said in err
    assert not (tmp_path / "newdir").exists()


def test_a_mismatch_names_both_files_and_makes_no_folder(tmp_path, capsys):
    a = P.Recording(np.zeros((64, 1000)), 500e3, P.paper_8x8(), P.paper_chirp())
    b = P.Recording(np.zeros((30, 1000)), 450e3, P.urtis_v1(), P.paper_chirp())
    P.save_recording(tmp_path / "a.h5", a)
    P.save_recording(tmp_path / "b.h5", b)
    out = tmp_path / "o" / "sub"
    args = ["compare", str(tmp_path / "a.h5"), "--sim", str(tmp_path / "b.h5"), "--out", str(out)]
    assert main(args) == 2
    err = _err(capsys)
    assert f"pair 0 (real: {tmp_path / 'a.h5'} recording 0; simulated: --sim " in err
    assert f"{tmp_path / 'b.h5'} recording 0)" in err
    assert "arrays (" in err and "sample rates (500000 vs 450000 Hz)" in err
    assert not (tmp_path / "o").exists()
