"""The path responses' groups (direct path, echoes) of the renderer's factorisation
(:func:`acousim.synth.render._groups`) and the call's energy of the echoes' noise
level (:func:`acousim.synth.signal_model._call_energy`)."""

import numpy as np

import processing as P
from acousim.core.echoes import Echoes
from acousim.synth import PathResponse
from acousim.synth.render import _groups, _response_factors, call_grid
from acousim.synth.signal_model import _call_energy

FS = 450e3


def test_groups_are_slices_when_the_direct_path_leads_else_masks_and_an_order():
    groups, order = _groups(np.array([0, 1, 2, 1]))
    assert order is None and groups == [slice(0, 1), slice(1, 4)]
    groups, order = _groups(np.array([2, 1]))  # no direct path
    assert order is None and groups == [slice(0, 2)]
    groups, order = _groups(np.array([1, 0, 2]))
    np.testing.assert_array_equal(order, [1, 0, 2])
    np.testing.assert_array_equal(groups[0], [False, True, False])
    np.testing.assert_array_equal(groups[1], [True, False, True])


def _echoes(order, rng):
    M, N = 4, order.size
    length = rng.uniform(1.0, 6.0, N)[None, :] + rng.uniform(0, 1e-3, (M, N))
    return Echoes(
        length / 343.0, rng.uniform(0.1, 1.0, (M, N)), length, order, rng.uniform(0, 1.2, N)
    )


def test_factors_of_paths_with_the_direct_path_moved_are_the_same_permuted():
    """The direct path first (slices) or second (masks and a reordering): the same
    terms, bit for bit, the paths' rows permuted."""
    rng = np.random.default_rng(3)
    first = _echoes(np.array([0, 1, 1, 2, 1, 2]), rng)
    perm = np.array([1, 0, 2, 3, 4, 5])
    moved = Echoes(
        first.delay_s[:, perm],
        first.gain[:, perm],
        first.path_length_m[:, perm],
        first.order[perm],
        first.emitter_angle_rad[perm],
    )
    t = np.arange(400) / FS
    call = np.hanning(t.size) * np.sin(2 * np.pi * 40e3 * t)  # a short tone burst
    n = 2048
    grid = call_grid(call, FS, n)
    response = PathResponse(emitter_radius_m=0.004)
    a = _response_factors(first, first.gain, grid.W, FS, n, response, grid)
    b = _response_factors(moved, moved.gain, grid.W, FS, n, response, grid)
    np.testing.assert_array_equal(b[0], a[0][:, perm])  # the gains (M, N)
    np.testing.assert_array_equal(b[1], a[1])  # U
    np.testing.assert_array_equal(b[2], a[2][perm])  # V (N, Q)
    np.testing.assert_array_equal(b[4], a[4])  # the direct path's terms
    assert a[4].any() and not a[4].all()


def test_call_energy_is_the_sampled_calls_sum_of_squares():
    call = P.rtis_call()
    energy, size = _call_energy(call, FS)
    sampled = call.sampled(FS)
    assert size == sampled.size
    np.testing.assert_allclose(energy, np.sum(sampled**2), rtol=1e-15)
