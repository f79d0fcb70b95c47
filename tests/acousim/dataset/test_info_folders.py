"""``acousim info`` on a folder written by ``acousim image``: its pictures, peaks.csv
(its rows) and images.h5; a folder acousim does not write says what info reads."""

from acousim.cli import main


def test_info_describes_a_folder_of_acousim_image(tmp_path, capsys):
    rec = tmp_path / "wall.h5"
    assert main(["simulate", "wall", "--out", str(rec), "--quiet"]) == 0
    img = tmp_path / "img"
    args = ["image", str(rec), "--out", str(img), "--method", "das", "--no-3d", "--quiet"]
    assert main([*args, "--images-h5"]) == 0
    capsys.readouterr()
    assert main(["info", str(img)]) == 0
    out = capsys.readouterr().out.splitlines()
    pictures = sorted(p.name for p in img.iterdir() if p.suffix == ".png")
    assert pictures and out[0] == (
        f"{img}: a folder written by acousim image: {len(pictures)} picture(s) "
        f"({', '.join(pictures)})"
    )
    rows = len((img / "peaks.csv").read_text().strip().splitlines()) - 1  # less the header
    assert rows >= 1
    assert out[1] == f"  peaks.csv: {rows} peak row(s) of 1 recording(s), method(s) das"
    assert out[2] == f"  {img / 'images.h5'}: images of 1 recording(s) (format acousim-images)"
    assert out[3].startswith("    [0] simulated (wall): das (range x elevation x azimuth (")


def test_info_on_another_folder_says_what_it_reads(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine\n")
    assert main(["info", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path}: not a folder acousim writes: no manifest.json" in err
    assert "peaks.csv, images.h5 or fan.png" in err and "metadata.yaml (a ROS 2 bag)" in err
