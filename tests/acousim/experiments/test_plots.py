"""The study's sweep plots: error bars on log axes."""

from __future__ import annotations

import numpy as np

from acousim.experiments.paper_study import _lower_bars


def test_a_lower_bar_reaching_zero_on_a_log_axis_stops_at_a_tenth_of_the_mean():
    mean, std = np.array([1e-3, 1e-3, 2.0]), np.array([5e-4, 3e-3, 2.0])
    low, clipped = _lower_bars(mean, std, log=True)
    assert clipped.tolist() == [False, True, True]
    assert np.allclose(mean - low, [5e-4, 1e-4, 0.2])  # drawn down to these
    low, clipped = _lower_bars(mean, std, log=False)  # a linear axis shows them whole
    assert not clipped.any() and np.array_equal(low, std)
