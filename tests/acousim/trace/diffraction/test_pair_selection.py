"""Which edge pairs the stage integrates edge to edge, checked against the full
computation (every pair integrated):

* the closed-form bound (:func:`acousim.trace.diffraction.pair_bound.pair_bound`) is at least
  every pair's largest path (bin);
* with a floor like the tracer's (a wall 1 m away, -80 dB), the pairs the stage
  skips have every path below the floor, and the stage's paths above the floor are
  the full computation's;
* the compiled kernel and the numpy path agree (within 1e-7 of the largest path:
  their cuts of edge 1 stop Newton's method at different points);
* integrating only some bins of path (the stage's fine pass after its coarse one)
  fills those bins exactly as the whole integral does.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from acousim.scene.model import Diffraction
from acousim.trace.diffraction.edge_to_edge import candidate_pairs
from acousim.trace.diffraction.pair_bound import pair_bound
from acousim.trace.diffraction.pairs import pair_elements, pair_elements_in, shortest_paths
from acousim.trace.diffraction.setup import StageContext
from acousim.trace.diffraction.stage import DiffractingGeometry, DiffractionOptions, diffract
from acousim.trace.world.edges import find_edges
from acousim.trace.world.embree import RayCaster
from processing.base.kernels import optional_kernel
from tests.acousim.trace.diffraction.test_edge_to_edge import plane_ids

#: a gain at the receiver 80 dB under a rigid wall 1 m away (1 / (2 m))
FLOOR = 0.5 * 1e-4
BIN_M = 0.25e-3


def room_objects() -> trimesh.Trimesh:
    """A door leaf (0.9 x 2 m, 4 cm thick) 1.5 m ahead, a 0.3 m box turned 23° 1 m
    ahead to the right, and a 4 cm plate 0.6 m ahead: long and short edges, rims,
    box faces and corners."""
    door = trimesh.creation.box([0.04, 0.9, 2.0])
    door.apply_translation([1.5, 0.6, 0.3])
    box = trimesh.creation.box([0.3, 0.3, 0.3])
    box.apply_transform(trimesh.transformations.rotation_matrix(0.4, [0, 0, 1]))
    box.apply_translation([1.0, -0.5, -0.2])
    h = 0.02
    corners = np.array([[0.6, -h, -h], [0.6, h, -h], [0.6, h, h], [0.6, -h, h]]) + [0, 0.1, 0.05]
    plate = trimesh.Trimesh(corners, [[0, 1, 2], [0, 2, 3]])
    return trimesh.util.concatenate([door, box, plate])


EMITTER, RECEIVER = np.array([0.0, 0.0, -0.012]), np.zeros(3)


@pytest.fixture(scope="module")
def stage():
    mesh = room_objects()
    geometry = DiffractingGeometry(
        find_edges(mesh), np.ones(len(mesh.faces)), face_plane=plane_ids(mesh)
    )
    return geometry, RayCaster(mesh.triangles, 1)


def _largest_bins(rows) -> np.ndarray:
    el = pair_elements(rows, EMITTER, RECEIVER, bin_m=BIN_M, max_path_m=8.0)
    largest = np.zeros(len(rows))
    np.maximum.at(largest, el.pair, np.abs(el.amplitude))
    return largest


def test_the_bound_is_above_every_pairs_largest_path(stage):
    geometry, caster = stage
    options = DiffractionOptions(max_path_m=8.0, settings=Diffraction(order=2))
    rows, _, _ = candidate_pairs(StageContext(geometry, caster, EMITTER, RECEIVER, options))
    assert len(rows) > 50
    largest = _largest_bins(rows)
    bound = pair_bound(rows, EMITTER, RECEIVER, max_excess_m=0.05, max_path_m=8.0, bin_m=BIN_M)
    assert (largest > 0).sum() > 50
    assert np.all(bound >= largest), np.max(largest / bound)


def test_what_the_selection_skips_is_below_the_floor(stage):
    """The stage with its selection against every pair integrated: the same paths
    above the floor (the skipped pairs' largest path is under it), and some pairs
    are skipped and some kept."""
    geometry, caster = stage

    def paths(select):
        options = DiffractionOptions(
            max_path_m=8.0, settings=Diffraction(order=2), floor_level=FLOOR, select_pairs=select
        )
        d = diffract(geometry, caster, EMITTER, RECEIVER, options)
        sel = (d.order == 2) & (
            np.abs(d.strength) / np.linalg.norm(d.anchor_m - RECEIVER, axis=1) >= FLOOR
        )
        return d, sel

    full, above_full = paths(False)
    chosen, above = paths(True)
    assert above_full.sum() > 20
    assert (chosen.order == 2).sum() < (full.order == 2).sum()  # pairs were skipped
    key = np.lexsort((full.first_leg_m[above_full], full.edge[above_full]))
    key_c = np.lexsort((chosen.first_leg_m[above], chosen.edge[above]))
    np.testing.assert_array_equal(full.edge[above_full][key], chosen.edge[above][key_c])
    np.testing.assert_allclose(
        full.strength[above_full][key], chosen.strength[above][key_c], rtol=1e-12
    )


def _kernel_and_numpy(rows):
    """The pairs' elements by the compiled kernel and by numpy, checked to agree: the
    same pairs, amplitudes within 1e-7 of the largest."""
    a = pair_elements(rows, EMITTER, RECEIVER, use_kernel=True)
    b = pair_elements(rows, EMITTER, RECEIVER, use_kernel=False)
    assert len(a) == len(b) > 1000
    np.testing.assert_array_equal(a.pair, b.pair)
    scale = np.max(np.abs(b.amplitude))
    np.testing.assert_allclose(a.amplitude, b.amplitude, rtol=0, atol=1e-7 * scale)
    return a, b


@pytest.mark.skipif(
    optional_kernel("acousim.trace.diffraction.pair_kernel") is None, reason="numba not installed"
)
def test_the_compiled_kernel_and_numpy_agree(stage):
    geometry, caster = stage
    options = DiffractionOptions(max_path_m=8.0, settings=Diffraction(order=2))
    rows, _, _ = candidate_pairs(StageContext(geometry, caster, EMITTER, RECEIVER, options))
    a, b = _kernel_and_numpy(rows)
    np.testing.assert_allclose(
        a.first_leg_m + a.second_leg_m, b.first_leg_m + b.second_leg_m, atol=1e-9
    )


@pytest.mark.skipif(
    optional_kernel("acousim.trace.diffraction.pair_kernel") is None, reason="numba not installed"
)
@pytest.mark.parametrize(
    "reflection", [(0.6, 0.9), (-1.0, 1.0), (0.0, 0.7), (-0.4, 0.0), (-1.5, -0.5)]
)
def test_the_kernel_and_numpy_agree_with_face_reflections(stage, reflection):
    """Faces that reflect less than fully (or invert: -1) weight the beta terms
    (R2, 1, 1, R1): the kernel's shortcuts for one term, for two of equal or (the
    last case, reflections beyond 1 only to get there) opposite weights, and its
    general sum, against the numpy path's four-term sums."""
    geometry, caster = stage
    options = DiffractionOptions(max_path_m=8.0, settings=Diffraction(order=2))
    rows, _, _ = candidate_pairs(StageContext(geometry, caster, EMITTER, RECEIVER, options))
    r1, r2 = reflection
    terms = np.array([r2, 1.0, 1.0, r1])
    n = len(rows)
    rows = dataclasses.replace(
        rows, terms1=np.tile(terms, (n, 1)), terms2=np.tile(terms[::-1], (n, 1))
    )
    a, b = _kernel_and_numpy(rows)


@pytest.mark.skipif(
    optional_kernel("acousim.trace.diffraction.pair_kernel") is None, reason="numba not installed"
)
def test_the_pairs_shared_among_threads_give_the_same_bytes(stage):
    """The kernel's pairs dealt out to two threads, each filling its own rows of
    the same bins: every path bit for bit as in one thread."""
    geometry, caster = stage
    options = DiffractionOptions(max_path_m=8.0, settings=Diffraction(order=2))
    rows, _, _ = candidate_pairs(StageContext(geometry, caster, EMITTER, RECEIVER, options))
    live = (np.ones((len(rows), 54), bool), 4 * BIN_M)
    one = pair_elements_in(rows, EMITTER, RECEIVER, live, max_path_m=8.0)
    two = pair_elements_in(
        rows, EMITTER, RECEIVER, live, max_path_m=8.0,
        workers=RayCaster(room_objects().triangles, 2),
    )  # fmt: skip
    assert len(one) > 1000
    for name in ("pair", "amplitude", "first_leg_m", "second_leg_m", "point_m", "first_point_m"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))


@pytest.mark.parametrize("live", ["random", "prefix"])
def test_the_live_bins_are_those_of_the_whole_integral(stage, live):
    """pair_elements_in with half the 1 mm bins of excess path live (chosen at
    random, seeded; or the first ones of each pair, as the stage's coarse pass
    mostly leaves them, up to a bin drawn per pair: the kernel stops a side of
    edge 2 at the pair's last live bin): every bin it fills is equal, bit for bit,
    to the same bin of the whole integral, and it fills every bin of the whole
    integral that lies in a live 1 mm bin."""
    geometry, caster = stage
    options = DiffractionOptions(max_path_m=8.0, settings=Diffraction(order=2))
    rows, _, _ = candidate_pairs(StageContext(geometry, caster, EMITTER, RECEIVER, options))
    rng = np.random.default_rng(1)
    if live == "random":
        mask = rng.random((len(rows), 54)) < 0.5
    else:
        mask = np.arange(54) <= rng.integers(0, 54, len(rows))[:, None]
    part = pair_elements_in(rows, EMITTER, RECEIVER, (mask, 4 * BIN_M), max_path_m=8.0)
    full = pair_elements(rows, EMITTER, RECEIVER, max_path_m=8.0)
    _, p_min = shortest_paths(rows, EMITTER, RECEIVER)

    def bins(el):
        path = el.first_leg_m + el.second_leg_m
        return {(k, round(p, 9)): a for k, p, a in zip(el.pair, path, el.amplitude)}, path

    got, _ = bins(part)
    whole, path = bins(full)
    fine_bin = np.floor((path - p_min[full.pair]) / BIN_M).astype(int)
    needed = mask[full.pair, np.minimum(fine_bin // 4, 53)]
    keys = list(whole)
    assert 0.3 * len(full) < len(part) < 0.8 * len(full)
    assert all(k in whole and whole[k] == v for k, v in got.items())
    assert all(keys[i] in got for i in np.flatnonzero(needed))
