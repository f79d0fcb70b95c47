"""The DAS image peaks of the corridor drive at some settings against a reference
setting: positions within one cell, levels within 1 dB, none lost or added above
-30 dB; and the waveform residual (dB re the reference's energy, and re the
echoes' energy: the direct path left out of the reference).

    python -m benchmarks.peaks_check '{"render_rate": "baseband"}' [--poses 10,20,30]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

import processing as P
from acousim.imaging.run import ImagingOptions
from acousim.scene import load_scene
from acousim.simulator import Simulator

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "corridor.toml"
FLOOR_DB = -30.0


def _recordings(overrides: dict, poses: list[int], **sensor) -> list[P.Recording]:
    scene = load_scene(SCENE)
    scene = dataclasses.replace(
        scene,
        simulation=dataclasses.replace(scene.simulation, **overrides),
        sensor=dataclasses.replace(scene.sensor, **sensor),
    )
    return Simulator(scene).run(poses)


def _peaks(rec: P.Recording) -> tuple[P.Peaks, P.Image]:
    opts = ImagingOptions(methods=("das",))
    image = P.acoustic_image(rec, "das", opts.settings(rec))
    return image.peaks(FLOOR_DB), image


def compare_peaks(ref: P.Recording, new: P.Recording) -> dict:
    """Peaks of `new` against those of `ref`: matched (within one cell in range,
    azimuth and elevation), the largest level difference of the matched (dB), the
    reference's peaks above -29 dB with no match (lost) and the new image's above
    -29 dB with no match (added): 1 dB of slack at the threshold."""
    (a, ia), (b, ib) = _peaks(ref), _peaks(new)
    step_r = ia.bin_range_m or np.min(np.diff(ia.range_m))
    step_a = np.min(np.diff(ia.azimuth_rad)) if ia.azimuth_rad.size > 1 else np.inf
    step_e = np.min(np.diff(ia.elevation_rad)) if ia.elevation_rad.size > 1 else np.inf

    def near(i, j):
        return (
            abs(a.range_m[i] - b.range_m[j]) <= 1.01 * step_r
            and abs(a.azimuth_rad[i] - b.azimuth_rad[j]) <= 1.01 * step_a
            and abs(a.elevation_rad[i] - b.elevation_rad[j]) <= 1.01 * step_e
        )

    pairs = [(i, j) for i in range(len(a)) for j in range(len(b)) if near(i, j)]
    got_a = {i for i, _ in pairs}
    got_b = {j for _, j in pairs}
    # each reference peak's best level match
    dl = []
    for i in got_a:
        dl.append(min(abs(a.level_db[i] - b.level_db[j]) for ii, j in pairs if ii == i))
    lost = [i for i in range(len(a)) if i not in got_a and a.level_db[i] > FLOOR_DB + 1]
    added = [j for j in range(len(b)) if j not in got_b and b.level_db[j] > FLOOR_DB + 1]
    # an unmatched peak whose cell the other image still holds within 1 dB (in the
    # 3x3x3 cells around it) is the same energy, no longer a local maximum there
    gone = [i for i in lost if _around(ib, a, i) < a.level_db[i] - 1]
    new_ = [j for j in added if _around(ia, b, j) < b.level_db[j] - 1]
    return {
        "peaks": len(a),
        "matched": len(got_a),
        "level_max_db": max(dl) if dl else 0.0,
        "lost": len(lost),
        "added": len(added),
        "lost_energy": len(gone),
        "added_energy": len(new_),
    }


def _around(image: P.Image, peaks: P.Peaks, k: int) -> float:
    """The strongest level (dB re the image's strongest cell) of `image` in the 3x3x3
    cells around peak k of `peaks`."""
    db = image.db()
    r = int(np.argmin(np.abs(image.range_m - peaks.range_m[k])))
    e = int(np.argmin(np.abs(image.elevation_rad - peaks.elevation_rad[k])))
    a = int(np.argmin(np.abs(image.azimuth_rad - peaks.azimuth_rad[k])))
    return float(db[max(r - 1, 0) : r + 2, max(e - 1, 0) : e + 2, max(a - 1, 0) : a + 2].max())


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("overrides", help="JSON of simulation settings to check")
    ap.add_argument("--reference", default="{}", help="JSON of the reference's settings")
    ap.add_argument("--poses", default="10,15,20,25,30,35,40,45")
    a = ap.parse_args(argv)
    poses = [int(x) for x in a.poses.split(",")]
    over, ref_over = json.loads(a.overrides), json.loads(a.reference)
    ref = _recordings(ref_over, poses)
    new = _recordings(over, poses)
    clean_ref = _recordings({**ref_over, "snr_db": np.inf}, poses)
    clean_new = _recordings({**over, "snr_db": np.inf}, poses)
    echoes = _recordings({**ref_over, "snr_db": np.inf}, poses, direct_path=False)
    num = sum(np.sum((x.samples - y.samples) ** 2) for x, y in zip(clean_new, clean_ref))
    tot = sum(np.sum(y.samples**2) for y in clean_ref)
    ech = sum(np.sum(y.samples**2) for y in echoes)
    print(
        f"waveform residual: {10 * np.log10(num / tot):.1f} dB re the reference's energy, "
        f"{10 * np.log10(num / ech):.1f} dB re its echoes' (noise-free, {len(poses)} poses)"
    )
    counts = ("peaks", "matched", "lost", "added", "lost_energy", "added_energy")
    worst = dict.fromkeys(counts, 0) | {"level_max_db": 0.0}
    for i, x, y in zip(poses, ref, new):
        c = compare_peaks(x, y)
        print(f"pose {i}: {c}")
        worst = {k: worst[k] + c[k] for k in counts} | {
            "level_max_db": round(max(worst["level_max_db"], c["level_max_db"]), 2)
        }
    print(f"DAS peaks above {FLOOR_DB:g} dB: {worst}")


if __name__ == "__main__":
    main()
