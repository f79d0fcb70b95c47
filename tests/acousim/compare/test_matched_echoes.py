"""A matched echo is an echo both recordings have: the real peak stands above the
real recording's noise floor (by how much is reported, and recomputed here from the
samples with scipy), and the simulated peak is a traced path (its ground truth), not
a side lobe. Noise has no echo, and then nothing is said to agree by construction."""

from __future__ import annotations

import json

import numpy as np
from scipy.signal import fftconvolve, hilbert

import processing as P
from acousim.cli import main
from acousim.compare.inputs import load_real_recordings
from acousim.scene import load_scene
from acousim.simulator import Simulator
from tests import REPO

PLATE_AZIMUTH_DEG = -8.0  # ertis_sample.toml: the plate's direction


def _above_floor_db(rec: P.Recording, range_m: float) -> float:
    """The echo at `range_m` over the noise floor, written out: matched filter
    (convolution with the time-reversed call), envelope power averaged over the
    microphones in 5 cm bins, the strongest bin within 5 cm of the range over the
    median of the last quarter of the bins."""
    x = rec.samples
    call = rec.waveform.sampled(rec.sample_rate_hz)
    mf = fftconvolve(x, call[None, ::-1], axes=1)[:, call.size - 1 : call.size - 1 + x.shape[1]]
    power = (np.abs(hilbert(mf, N=2 * x.shape[1], axis=1)[:, : x.shape[1]]) ** 2).mean(axis=0)
    r = rec.time_s() * rec.speed_of_sound_m_s / 2
    edges = np.arange(0, r[-1] + 0.05, 0.05)
    idx = np.clip(np.digitize(r, edges) - 1, 0, len(edges) - 2)
    profile = np.bincount(idx, power, len(edges) - 1)
    centres = (edges[1:] + edges[:-1]) / 2
    floor = np.median(profile[int(len(profile) * 0.75) :])
    return 10 * np.log10(profile[np.abs(centres - range_m) <= 0.05].max() / floor)


def test_the_real_samples_echo_is_matched_and_the_side_lobe_is_not(tmp_path, capsys):
    args = ["compare", "rtisdev-sample", "--scene", str(REPO / "scenes" / "ertis_sample.toml")]
    assert main([*args, "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    das = json.loads((tmp_path / "comparison.json").read_text())["images"]["das"]
    (echo,) = das["matched"]  # the one plate: one echo
    assert echo["sim_truth_kind"] != ""
    assert abs(echo["sim"]["azimuth_deg"] - PLATE_AZIMUTH_DEG) <= 2.0
    # how far it stands above the floor, against the recomputation from the samples
    c = load_scene(REPO / "scenes" / "ertis_sample.toml").environment.speed_of_sound_m_s
    (real,) = load_real_recordings("rtisdev-sample", speed_of_sound_m_s=c)
    expected = _above_floor_db(real, echo["real"]["range_m"])
    assert echo["real_above_noise_floor_db"] > 20
    assert abs(echo["real_above_noise_floor_db"] - expected) < 1.0
    # the side lobe the sparse array puts at about +52 deg: paired, not an echo
    lobes = [r for r in das["rejected_pairs"] if r["reason"] == "simulated peak not traced"]
    assert lobes and all(abs(r["sim"]["azimuth_deg"] - PLATE_AZIMUTH_DEG) > 30 for r in lobes)
    # the printed line has the elevation and the margin over the floor
    line = f"el {echo['real']['elevation_deg']:+.0f}° ({echo['real_above_noise_floor_db']:+.1f} dB"
    assert line in out
    assert "no other matched echo" in out
    assert "agrees on that echo by construction" in out


def test_noise_has_no_echo_and_nothing_agrees_by_construction(tmp_path, capsys):
    """Gaussian noise (seeded) in place of a recording of the bundled wall."""
    (sim,) = Simulator(load_scene(REPO / "scenes" / "wall.toml")).run()
    noise = np.random.default_rng(5).normal(size=sim.samples.shape)
    real = sim.with_samples(noise).with_truth(None)
    P.save_recording(tmp_path / "noise.h5", real)
    assert main(["compare", str(tmp_path / "noise.h5"), "--scene", "wall"]) == 0
    out = capsys.readouterr().out
    assert "das: no echo above the noise floor in the real recording" in out
    assert "das echo 0" not in out
    assert "by construction" not in out
