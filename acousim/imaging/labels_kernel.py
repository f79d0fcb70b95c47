"""Compiled per-cell class energies of a label map
(:func:`acousim.imaging.labels.label_map`; numba, optional: without numba the sparse
product there runs).

One range bin at a time: the paths reaching the bin, in path order, add their range
taper times their angle taper to their class's row of a (C, G) table; then per
direction the classes' energies are summed in class order and the strongest class
taken (the first of equals).  The same products summed in the same order as the
sparse product (scipy sums each output over the paths in order), so the two give
the same bits (``tests/acousim/imaging/test_labels.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def cell_classes(
    range_ptr, range_path, range_val, angle_ptr, angle_dir, angle_val, cls, n_classes, total, top
):  # pragma: no cover - compiled
    """Fill `total` (R, G) with each cell's energy summed over classes in class order
    and `top` (R, G) integers with its strongest class (-1: none with energy), every
    cell written (they may come uninitialised).

    range_ptr (R + 1,), range_path, range_val : the range kernel by bin (CSC of the
    paths' (P, R) kernel, paths in order within a bin); angle_ptr (P + 1,),
    angle_dir, angle_val : the angle kernel by path (CSR of (P, G)); cls (P,) each
    path's class in 0..n_classes-1."""
    R, G = total.shape
    acc = np.zeros((n_classes, G))
    class_hit = np.zeros(n_classes, np.bool_)
    classes = np.empty(n_classes, np.int64)
    for r in range(R):
        total[r, :] = 0.0  # the cells no path reaches (each row first touched here)
        top[r, :] = -1
        n_classes_hit = 0
        lo, hi = G, -1  # the directions the bin's paths reach lie within lo..hi
        for j in range(range_ptr[r], range_ptr[r + 1]):
            p = range_path[j]
            v = range_val[j]
            c = cls[p]
            if not class_hit[c]:
                class_hit[c] = True
                classes[n_classes_hit] = c
                n_classes_hit += 1
            start, end = angle_ptr[p], angle_ptr[p + 1]
            if end > start:  # a path's directions come in order
                lo = min(lo, angle_dir[start])
                hi = max(hi, angle_dir[end - 1])
            for k in range(start, end):
                acc[c, angle_dir[k]] += v * angle_val[k]
        # the classes of this bin in class order (the others add zeros); a direction
        # no path reached sums to 0 with no class: as the row was filled
        order = np.sort(classes[:n_classes_hit])
        for i in range(n_classes_hit):
            class_hit[order[i]] = False
        for g in range(lo, hi + 1):
            s = 0.0
            best = 0.0
            win = -1
            for ci in range(n_classes_hit):
                c = order[ci]
                x = acc[c, g]
                s += x
                if x > best:
                    best = x
                    win = c
                acc[c, g] = 0.0
            total[r, g] = s
            top[r, g] = win


@njit(cache=True, nogil=True, error_model="numpy")
def pick_labels(
    total, top, class_object, class_order, floor_ratio, out_object, out_order
):  # pragma: no cover - compiled
    """The labels of :func:`cell_classes`' cells: where a class wins (`top` >= 0) and
    the cell's `total` is at least `floor_ratio` times the largest total, that
    class's object and order (`class_object`, `class_order` (C,)), else -1; written
    to every cell of `out_object` and `out_order` (R, G).  As numpy's ``top >= 0 &
    total >= total.max() * floor_ratio``."""
    R, G = total.shape
    most = 0.0
    for r in range(R):
        for g in range(G):
            if total[r, g] > most:
                most = total[r, g]
    floor = most * floor_ratio
    for r in range(R):
        for g in range(G):
            c = top[r, g]
            if c >= 0 and total[r, g] >= floor:
                out_object[r, g] = class_object[c]
                out_order[r, g] = class_order[c]
            else:
                out_object[r, g] = -1
                out_order[r, g] = -1


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
