"""Frequency-dependent materials at a diffracting edge: the image terms of a face
whose material is a table over frequency follow the table.

Independent reference: with both faces of a wedge reflecting with the factor R, the
field is linear in R between the exact rigid wedge (R = 1, Neumann) and the exact
pressure-release wedge (R = -1, Dirichlet): ``(1 + R) / 2 u_N + (1 - R) / 2 u_D``,
both from the wedge's series (tests/acousim/trace/diffraction/test_first_order.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from acousim.trace import KIND
from acousim.trace.diffraction.btm import edge_elements
from acousim.trace.tracer import Tracer
from tests.acousim.trace.diffraction.test_first_order import cyl, geometric, wedge_series
from tests.oracles.scenes import first_pose, rigid_scene, screen, square_faces, turn_z

C = 343.0
TABLE_KHZ = [20.0, 35.0, 45.0, 85.0]
TABLE_R = [1.0, 1.0, 0.5, 0.5]


@pytest.mark.parametrize("R", [0.5, 0.0])
def test_wedge_with_reflecting_faces_is_the_mean_of_rigid_and_soft(R):
    """The BTM elements with both faces' factor R against the exact series: a thin
    screen, source 0.15 m from the edge, receivers lit, on the reflection boundary's
    two sides and in the shadow, 30 and 70 kHz: within 0.5 dB and 3 degrees."""
    wedge, th_s, dz = 2 * np.pi, np.deg2rad(60.0), 0.05
    th_r = np.deg2rad([150.0, 120 - 1e-5, 120 + 1e-5, 265.0, 300.0])
    for f in (30e3, 70e3):
        k = 2 * np.pi * f / C
        rigid = wedge_series(wedge, 0.15, th_s, 0.10, th_r, dz, k)
        soft = wedge_series(wedge, 0.15, th_s, 0.10, th_r, dz, k, soft=True)
        exact = (1 + R) / 2 * rigid + (1 - R) / 2 * soft
        ours = []
        for t in th_r:
            el = edge_elements(
                screen(angle_rad=wedge, reflection=(R, R)),
                cyl(0.15, th_s, 0.0),
                cyl(0.10, t, dz),
            )
            path = el.first_leg_m + el.second_leg_m
            diffracted = np.sum(el.amplitude * np.exp(-1j * k * path))
            ours.append(geometric(wedge, 0.15, th_s, 0.10, t, dz, k, R) + diffracted)
        ours = np.array(ours)
        err_db = 20 * np.log10(np.abs(ours) / np.abs(exact))
        assert np.max(np.abs(err_db)) < 0.5, (f, err_db)
        assert np.max(np.abs(np.angle(ours / exact))) < np.deg2rad(3)


def _screen_paths(tmp_path: Path, material: dict, order: int = 1):
    """The diffraction paths of a 0.6 m square thin screen at 1 m, turned 40 degrees
    (no specular echo: edges only), and the world's material spectra; `order` 2:
    edge to edge too."""
    quads = square_faces("plate", 0.6, turn_z(40.0), [1.0, 0, 0])
    simulation = {
        "max_range_m": 2.0,
        "rays": 2000,
        "diffraction": {"order": order},
        "energy_floor_db": -200.0,
        "beam_deg": 60.0,
    }
    scene = rigid_scene(tmp_path, quads, simulation, material)
    pose, _, r = first_pose(scene)
    tracer = Tracer(scene, threads=1)
    paths = tracer.trace(pose)
    return paths, tracer.world.spectra, r


def _spectrum(paths, r, freqs, factor=None):
    last = np.linalg.norm(paths.anchor_m - r, axis=1)
    k = 2 * np.pi * np.asarray(freqs) / C
    terms = paths.strength / last * np.exp(-1j * k[:, None] * (paths.first_leg_m + last))
    if factor is not None:
        terms = terms * factor
    return terms.sum(axis=1)


def test_table_material_at_an_edge_is_the_single_number_at_each_frequency(tmp_path):
    """A screen whose material is a table (R 1 below 35 kHz, 0.5 above 45 kHz): its
    edge echo at 25 and 70 kHz equals that of the same screen with the single number
    R(f) there (which the wedge tests check against the exact solutions), within
    0.05 dB and 1 degree."""
    table, spectra, r = _screen_paths(
        tmp_path, {"frequencies_khz": TABLE_KHZ, "reflection": TABLE_R}
    )
    assert spectra is not None
    edge = table.kind == KIND["diffraction"]
    assert edge.sum() > 0 and not (table.kind == KIND["specular"]).any()
    # the image terms count one interaction with the table each
    assert table.interactions[edge].sum() > 0
    for f, R in ((25e3, 1.0), (70e3, 0.5)):
        single, _, _ = _screen_paths(tmp_path, {"reflection": R})
        d1 = single.kind == KIND["diffraction"]
        factor = spectra.factor(np.array([f]), table.interactions[edge])  # (1, N)
        ours = _spectrum(
            table.select(edge) if hasattr(table, "select") else _sel(table, edge), r, [f], factor
        )
        ref = _spectrum(_sel(single, d1), r, [f])
        assert abs(20 * np.log10(abs(ours[0]) / abs(ref[0]))) < 0.05
        assert abs(np.angle(ours[0] / ref[0])) < np.deg2rad(1)
    # the level changes with the table: 0.5 on the image terms is not a mere scale
    lo = _spectrum(_sel(table, edge), r, [70e3])[0]
    hi = _spectrum(
        _sel(table, edge), r, [70e3], spectra.factor(np.array([70e3]), table.interactions[edge])
    )[0]
    assert abs(20 * np.log10(abs(hi) / abs(lo))) > 0.5


def _sel(paths, keep):
    from dataclasses import fields, replace

    return replace(paths, **{f.name: getattr(paths, f.name)[keep] for f in fields(paths)})


def test_table_material_edge_to_edge_is_the_single_number_at_each_frequency(tmp_path):
    """Edge to edge over the same screen (its rims share its face): the paths with a
    table material, split into the wedges' parts with and without the face's image
    terms (each counting its interactions), equal the single-number screen's at 25
    and 70 kHz within 0.05 dB and 1 degree."""
    table, spectra, r = _screen_paths(
        tmp_path, {"frequencies_khz": TABLE_KHZ, "reflection": TABLE_R}, order=2
    )
    e2e = (table.kind == KIND["diffraction"]) & (table.order == 2)
    assert e2e.sum() > 0
    # image terms of one face counted once or twice (the two wedges' images)
    assert set(np.unique(table.interactions[e2e].sum(axis=1))) >= {0, 1, 2}
    for f, R in ((25e3, 1.0), (70e3, 0.5)):
        single, _, _ = _screen_paths(tmp_path, {"reflection": R}, order=2)
        d2 = (single.kind == KIND["diffraction"]) & (single.order == 2)
        factor = spectra.factor(np.array([f]), table.interactions[e2e])
        ours = _spectrum(_sel(table, e2e), r, [f], factor)
        ref = _spectrum(_sel(single, d2), r, [f])
        assert abs(20 * np.log10(abs(ours[0]) / abs(ref[0]))) < 0.05, f
        assert abs(np.angle(ours[0] / ref[0])) < np.deg2rad(1), f
