"""The truth label map (acousim.imaging.labels.label_map) against a second
implementation written here from its definition, cell by cell on a tiny grid: each
path's energy spread by a Gaussian taper of full width at half maximum one cell in
range and in angle, cut at one cell; per cell the (object, order) class with the
most summed energy (the first of equals in (object, order) order), none where the
cell's total lies more than the dynamic range below the strongest cell's or no path
reaches it; paths 30 dB below that floor (re the strongest path) left out."""

import numpy as np
import pytest

from acousim.imaging import labels
from acousim.imaging.labels import NEGLIGIBLE_DB, label_map


def _directions(el_deg, az_deg) -> np.ndarray:
    el, az = np.meshgrid(np.deg2rad(el_deg), np.deg2rad(az_deg), indexing="ij")
    u = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1)
    return u.reshape(-1, 3)


def _without_numba(monkeypatch) -> None:
    """The label maps' numpy forms from here on (as without numba installed)."""
    monkeypatch.setattr(labels, "optional_kernel", lambda *a: None)


def _reference(rng, dirs, pos, energy, obj, order, cell, dr_db):
    """Cell by cell, path by path: (object, order) per cell, -1 none."""
    wr, wa = cell
    keep = energy >= energy.max() * 10 ** (-(dr_db + NEGLIGIBLE_DB) / 10)
    classes = sorted({(int(o), int(k)) for o, k, ok in zip(obj, order, keep) if ok})
    energy_of = np.zeros((len(rng), len(dirs), len(classes)))
    for r_i, r in enumerate(rng):
        for g_i, u in enumerate(dirs):
            for p in np.flatnonzero(keep):
                dist = np.linalg.norm(pos[p])
                cos = float(np.dot(pos[p] / dist, u))
                ang = np.arccos(min(max(cos, -1.0), 1.0))
                if abs(r - dist) > wr or cos < np.cos(wa):
                    continue  # beyond one cell of the path
                taper = np.exp(-4 * np.log(2) * (((r - dist) / wr) ** 2 + (ang / wa) ** 2))
                energy_of[r_i, g_i, classes.index((obj[p], order[p]))] += energy[p] * taper
    total = energy_of.sum(axis=-1)
    out_obj = np.full(total.shape, -1)
    out_order = np.full(total.shape, -1)
    for r_i in range(len(rng)):
        for g_i in range(len(dirs)):
            if total[r_i, g_i] <= 0 or total[r_i, g_i] < total.max() * 10 ** (-dr_db / 10):
                continue
            best = int(np.argmax(energy_of[r_i, g_i]))  # the first of equals
            out_obj[r_i, g_i], out_order[r_i, g_i] = classes[best]
    return out_obj, out_order


def _scattered(rnd, n: int, el_deg: float, az_deg: float) -> np.ndarray:
    """`n` points (n, 3) at 0.8-1.2 m, elevation within +-`el_deg`, azimuth within
    +-`az_deg` (uniform, from `rnd`)."""
    r = rnd.uniform(0.8, 1.2, n)
    el = np.deg2rad(rnd.uniform(-el_deg, el_deg, n))
    az = np.deg2rad(rnd.uniform(-az_deg, az_deg, n))
    return r[:, None] * np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1)


@pytest.mark.parametrize("use_kernel", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_label_map_matches_a_cell_by_cell_reference(seed, use_kernel, monkeypatch):
    """Twenty paths of five objects and orders 1-3, some 50 dB down, on 21 range bins
    x 5 x 9 directions: every cell labelled as the reference labels it."""
    if not use_kernel:
        _without_numba(monkeypatch)
    rnd = np.random.default_rng(seed)
    rng = np.arange(0.8, 1.21, 0.02)
    dirs = _directions(np.arange(-20, 21, 10.0), np.arange(-40, 41, 10.0))
    n = 20
    pos = _scattered(rnd, n, 25.0, 45.0)
    energy = 10 ** (-rnd.uniform(0, 6, n))  # 0 to 60 dB down
    obj, order = rnd.integers(0, 5, n), rnd.integers(1, 4, n)
    cell, dr = (0.06, np.deg2rad(15)), 20.0
    lab = label_map(
        range_m=rng,
        directions=dirs,
        positions_m=pos,
        energy=energy,
        object_index=obj,
        order=order,
        cell=cell,
        dynamic_range_db=dr,
    )
    want_obj, want_order = _reference(rng, dirs, pos, energy, obj, order, cell, dr)
    assert (want_obj >= 0).sum() > 50 and (want_obj < 0).sum() > 50  # both kinds of cell
    assert len(np.unique(want_obj[want_obj >= 0])) >= 3  # several classes win somewhere
    np.testing.assert_array_equal(lab.object_index, want_obj)
    np.testing.assert_array_equal(lab.order, want_order)


@pytest.mark.parametrize("use_kernel", [True, False])
def test_equal_classes_give_the_cell_to_the_first(use_kernel, monkeypatch):
    """Two paths at the same place with the same energy, of objects 3 and 1: every
    cell they reach goes to object 1 (the first in (object, order) order)."""
    if not use_kernel:
        _without_numba(monkeypatch)
    rng = np.arange(0.9, 1.11, 0.02)
    dirs = _directions(np.array([0.0]), np.arange(-20, 21, 5.0))
    lab = label_map(
        range_m=rng,
        directions=dirs,
        positions_m=[[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
        energy=[1.0, 1.0],
        object_index=[3, 1],
        order=[1, 1],
        cell=(0.1, np.deg2rad(20)),
        dynamic_range_db=40.0,
    )
    assert (lab.object_index >= 0).sum() > 20
    assert set(np.unique(lab.object_index)) - {-1} == {1}


@pytest.mark.parametrize("seed", [3, 4])
def test_the_kernel_gives_the_numpy_forms_bits(seed, monkeypatch):
    """The compiled kernels (acousim.imaging.labels_kernel) against the numpy forms
    they replace (the directions within a cell of each path; the sparse product of
    the per-cell sums), on 300 paths of 12 classes crowding a 41 x 7 x 11 grid:
    the same kernels' entries, every cell's summed energy the same float, every
    cell's class the same."""
    pytest.importorskip("numba")
    from acousim.imaging.labels import _factors, _total_and_top

    rnd = np.random.default_rng(seed)
    rng = np.arange(0.8, 1.21, 0.01)
    dirs = _directions(np.arange(-30, 31, 10.0), np.arange(-50, 51, 10.0))
    n = 300
    pos = _scattered(rnd, n, 35.0, 55.0)
    energy = 10 ** (-rnd.uniform(0, 4, n))
    k_range, k_angle = _factors(rng, dirs, pos, energy, 0.05, 0.3, chunk=64)
    cls = rnd.integers(0, 12, n)
    total, top = _total_and_top(k_range, k_angle, cls, 12)
    _without_numba(monkeypatch)
    want_range, want_angle = _factors(rng, dirs, pos, energy, 0.05, 0.3, chunk=64)
    for got, want in ((k_range, want_range), (k_angle, want_angle)):
        for name in ("data", "indices", "indptr"):
            assert np.array_equal(getattr(got, name), getattr(want, name))
    want_total, want_top = _total_and_top(k_range, k_angle, cls, 12)
    assert (want_top >= 0).sum() > 1000 and len(np.unique(want_top)) == 13
    np.testing.assert_array_equal(top, want_top)
    assert np.array_equal(total, want_total)  # bit for bit
