"""Compiled per-cell class energies of a label map
(:func:`acousim.imaging.labels.label_map`; numba, optional: without numba the sparse
product there runs).

A block of range bins at a time (its (bins, C, G) table in cache): the paths reaching
the block, in path order, read their angle taper once and add it, times their range
taper, to their class's row of each of their bins in the block; then per cell the
classes' energies are summed in class order and the strongest class taken (the
first of equals); only the cells that can be labelled are listed.  The same
products summed in the same order as the sparse product (scipy sums each output
over the paths in order), so the two give the same bits (``tests/acousim/imaging/test_labels.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def cell_classes(
    range_ptr,
    range_bin,
    range_val,
    angle_ptr,
    angle_dir,
    angle_val,
    cls,
    n_classes,
    shape,
    block_bins,
    floor_ratio,
    cells,
    total,
    top,
):  # pragma: no cover - compiled
    """The cells of a (R, G) grid (`shape`) that may be labelled: each cell's energy
    summed over classes in class order and its strongest class (the first of
    equals), listed where a class has energy there and the sum is at least
    `floor_ratio` times the largest sum met so far (so every cell at least
    `floor_ratio` times the largest sum of all, and that one, is listed): written to
    the starts of `cells` (flat, r G + g), `total` and `top` (each R G long at most
    needed); returns their number.

    range_ptr (P + 1,), range_bin, range_val : the range kernel by path (CSR of the
    paths' (P, R) kernel, each path's bins in order); angle_ptr (P + 1,),
    angle_dir, angle_val : the angle kernel by path (CSR of (P, G)); cls (P,) each
    path's class in 0..n_classes-1.  `block_bins` range bins at a time, their
    (bins, classes, G) energies summed path by path in path order."""
    R, G = shape
    acc = np.zeros((block_bins, n_classes, G))
    m = 0
    most = 0.0
    for b0 in range(0, R, block_bins):
        b1 = min(b0 + block_bins, R)
        for p in range(range_ptr.size - 1):
            j0, j1 = range_ptr[p], range_ptr[p + 1]
            if j1 == j0 or range_bin[j0] >= b1 or range_bin[j1 - 1] < b0:
                continue  # none of the path's bins in this block
            c = cls[p]
            for j in range(j0, j1):
                r = range_bin[j]
                if r < b0 or r >= b1:
                    continue
                v = range_val[j]
                row = acc[r - b0, c]
                for k in range(angle_ptr[p], angle_ptr[p + 1]):
                    row[angle_dir[k]] += v * angle_val[k]
        for r in range(b0, b1):
            for g in range(G):
                s = 0.0
                best = 0.0
                win = -1
                for c in range(n_classes):  # class order; a class not there adds 0
                    x = acc[r - b0, c, g]
                    if x != 0.0:
                        s += x
                        if x > best:
                            best = x
                            win = c
                        acc[r - b0, c, g] = 0.0
                if win >= 0:
                    if s > most:
                        most = s
                    if s >= most * floor_ratio:
                        cells[m] = r * G + g
                        total[m] = s
                        top[m] = win
                        m += 1
    return m


@njit(cache=True, nogil=True, error_model="numpy")
def near_directions(dots, cos_cut, cols, values, counts):  # pragma: no cover - compiled
    """The entries of `dots` (n, G) at or above `cos_cut`, row by row, each row's in
    column order (as ``np.nonzero(dots >= cos_cut)``): their columns and values
    written to the starts of `cols` and `values` (n G,), each row's count to `counts`
    (n,); returns their number."""
    m = 0
    for i in range(dots.shape[0]):
        start = m
        for g in range(dots.shape[1]):
            x = dots[i, g]
            if x >= cos_cut:
                cols[m] = g
                values[m] = x
                m += 1
        counts[i] = m - start
    return m
