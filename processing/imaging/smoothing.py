"""Covariance estimates, plain and 2D spatially smoothed (FSS and FBSS).

Forward spatial smoothing (FSS) averages the covariances of every overlapping
Lz x Ly subarray of a URA; forward-backward smoothing (FBSS) also averages their
exchange-conjugates ``J R* J``, which decorrelates coherent echoes (the paper's
section III-D).  Subarray snapshots are stacked so the smoothed covariance is one
batched matrix product over range bins.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from processing.base.errors import InputError

__all__ = ["covariance", "smoothed_covariance", "subarray_snapshots", "default_subarray"]


def covariance(x: np.ndarray) -> np.ndarray:
    """Sample covariance per range bin.

    x : (M, R, K) snapshots.  Returns (R, M, M) Hermitian, ``X X^H / K``.
    """
    X = np.moveaxis(x, 0, 1)  # (R, M, K)
    return (X @ X.conj().transpose(0, 2, 1)) / X.shape[-1]


def default_subarray(shape: tuple[int, int]) -> tuple[int, int]:
    """The paper's proportion (5 of 8) applied to each dimension, at least 1."""
    nz, ny = (max(1, int(round(n * 5 / 8))) for n in shape)
    return nz, ny


def subarray_snapshots(
    x_grid: np.ndarray, subarray: tuple[int, int], *, forward_backward: bool = False
) -> np.ndarray:
    """The snapshots Y (R, L, S) whose ``Y Y^H / S`` is the smoothed covariance.

    Every subarray position (Pz x Py) of every measurement (K) is one snapshot,
    S = Pz Py K; forward-backward appends the exchange-conjugates ``J Y*`` (2S).
    """
    nz, ny = x_grid.shape[:2]
    lz, ly = (int(v) for v in subarray)
    if not (1 <= lz <= nz and 1 <= ly <= ny):
        raise InputError(f"subarray {subarray} must fit in the {nz}x{ny} array and be >= 1x1")
    win = sliding_window_view(x_grid, (lz, ly), axis=(0, 1))  # (Pz, Py, R, K, Lz, Ly)
    R = x_grid.shape[2]
    Y = np.moveaxis(win, 2, 0).reshape(R, -1, lz * ly).transpose(0, 2, 1)  # (R, L, S)
    if forward_backward:
        Y = np.concatenate([Y, Y[:, ::-1, :].conj()], axis=-1)
    return Y


def smoothed_covariance(
    x_grid: np.ndarray, subarray: tuple[int, int], *, forward_backward: bool = False
) -> np.ndarray:
    """Spatially smoothed covariance per range bin.

    Parameters
    ----------
    x_grid : ndarray, shape (Nz, Ny, R, K)
        Snapshots on the URA grid (rows along z, columns along y).
    subarray : (Lz, Ly)
        Subarray size, at most the array size.
    forward_backward : bool
        FBSS instead of FSS.

    Returns
    -------
    ndarray, shape (R, L, L), L = Lz * Ly, in row-major subarray order.
    """
    Y = subarray_snapshots(x_grid, subarray, forward_backward=forward_backward)
    C = (Y @ Y.conj().transpose(0, 2, 1)) / Y.shape[-1]
    if forward_backward:  # exactly centro-Hermitian despite rounding
        C = 0.5 * (C + C[:, ::-1, ::-1].conj())
    return C
