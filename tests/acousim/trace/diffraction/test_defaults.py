"""Edge diffraction at the DEFAULT settings (a scene that says nothing about
diffraction: first order on every edge, edge to edge where a pair can reach the
energy floor, the default -80 dB floor and 1 mm step) against independent
references:

* the cached full-wave levels of benchmarks/data/fullwave.csv (our boundary-element
  reference, bempp-cl, computed by benchmarks/fullwave; monostatic, rigid 40 mm
  plate and cube at 0.5 m): band power within 1 dB and every frequency within 3 dB
  where the reference is within 10 dB of its band power;
* physical optics (the Kirchhoff integral written in
tests/acousim/trace/diffraction/test_first_order.py) for
  a 5 cm plate facing the sensor (within 1 dB) and a 0.5 m plate whose mirror point
  misses it (within 3 dB).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from acousim.scene.model import Diffraction
from acousim.trace import KIND
from tests import REPO
from tests.acousim.trace.diffraction.test_first_order import physical_optics
from tests.oracles.scenes import rigid_scene, spectrum, square_faces, trace_first_pose, turn_z

C = 343.0
FULLWAVE = REPO / "benchmarks" / "data" / "fullwave.csv"


def _faces(kind: str, size: float, turn_deg: float, distance: float) -> list[np.ndarray]:
    """Corners (4, 3) of a square plate (facing -x before the turn) or of a cube's
    six faces, centred at (distance, 0, 0), turned about z."""
    return square_faces(kind, size, turn_z(turn_deg), [distance, 0, 0])


def default_paths(tmp_path: Path, quads: list[np.ndarray], max_range_m: float, beam_deg=60.0):
    """The paths of one pose of a uRTIS facing +x at the origin, for rigid faces
    `quads`, with every simulation setting at its default but the range and the
    beam (nothing about diffraction)."""
    scene = rigid_scene(tmp_path, quads, {"max_range_m": max_range_m, "beam_deg": beam_deg})
    assert scene.simulation.diffraction == Diffraction(enabled=True, order=2)
    return trace_first_pose(scene)


def _fullwave() -> dict[tuple[str, int], tuple[np.ndarray, np.ndarray]]:
    """(object, angle) -> (frequencies, levels in dB re the wall), the finest mesh
    of each row."""
    with FULLWAVE.open() as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    best: dict[tuple, tuple[float, float]] = {}
    for r in rows:
        key = (r["object"], round(float(r["angle_deg"])), float(r["frequency_hz"]))
        if key not in best or float(r["ppw"]) > best[key][1]:
            best[key] = (float(r["level_db"]), float(r["ppw"]))
    out: dict[tuple[str, int], tuple[list, list]] = {}
    for (obj, angle, f), (level, _) in sorted(best.items()):
        out.setdefault((obj, angle), ([], []))
        out[(obj, angle)][0].append(f)
        out[(obj, angle)][1].append(level)
    return {k: (np.array(a), np.array(b)) for k, (a, b) in out.items()}


CASES = [
    ("plate", 0),
    ("plate", 5),
    ("plate", 10),
    ("plate", 20),
    ("plate", 30),
    ("cube", 0),
    ("cube", 45),
]


@pytest.mark.parametrize("obj,angle", CASES)
def test_small_objects_at_default_settings_match_the_full_wave_reference(tmp_path, obj, angle):
    """40 mm rigid plate (face on and turned 5-30°) and cube (face on, turned 45°)
    at 0.5 m: band power (the full-wave frequencies of 20-80 kHz) within 1 dB, and
    within 3 dB at each frequency whose reference level is within 10 dB of the
    reference's band power."""
    freqs, ref_db = _fullwave()[(obj, angle)]
    paths, _, r = default_paths(tmp_path, _faces(obj, 0.04, angle, 0.5), 1.5)
    k = 2 * np.pi * freqs / C
    ours_db = 20 * np.log10(np.abs(spectrum(paths, r, k)) * 2 * 0.5)  # re the wall 1 / (2 d)

    def band(db):
        return 10 * np.log10(np.mean(10 ** (db / 10)))

    assert abs(band(ours_db) - band(ref_db)) < 1.0, (band(ours_db), band(ref_db))
    loud = ref_db >= band(ref_db) - 10
    assert loud.sum() >= 3
    err = ours_db - ref_db
    assert np.max(np.abs(err[loud])) < 3.0, dict(zip(freqs[loud], np.round(err[loud], 2)))


FREQS = np.linspace(20e3, 85e3, 14)


def test_five_centimetre_plate_at_default_settings_matches_physical_optics(tmp_path):
    """A 5 cm rigid plate 2 m ahead, facing the sensor: geometric optics alone is an
    infinite wall's echo (12 dB too loud in band); at the defaults within 1 dB of
    physical optics at every frequency of 20-85 kHz."""
    quads = _faces("plate", 0.05, 0.0, 2.0)
    paths, e, r = default_paths(tmp_path, quads, 3.0)
    assert ((paths.kind == KIND["diffraction"]) & (paths.order == 2)).any()  # edge to edge
    k = 2 * np.pi * FREQS / C
    err = 20 * np.log10(
        np.abs(spectrum(paths, r, k)) / np.abs(physical_optics(quads[0], e, r, k, 400))
    )
    assert np.max(np.abs(err)) < 1.0, err


@pytest.mark.parametrize("turn", [7.5, 10.0, 20.0])
def test_plate_missing_its_mirror_point_at_default_settings_matches_physical_optics(tmp_path, turn):
    """A 0.5 m rigid plate 2 m ahead turned so that its mirror point misses it (no
    specular echo; silent under geometric optics): at the defaults within 3 dB of
    physical optics at every frequency of 20-85 kHz."""
    quads = _faces("plate", 0.5, turn, 2.0)
    paths, e, r = default_paths(tmp_path, quads, 3.0)
    assert not (paths.kind == KIND["specular"]).any()
    k = 2 * np.pi * FREQS / C
    err = 20 * np.log10(
        np.abs(spectrum(paths, r, k)) / np.abs(physical_optics(quads[0], e, r, k, 800))
    )
    assert np.max(np.abs(err)) < 3.0, err
