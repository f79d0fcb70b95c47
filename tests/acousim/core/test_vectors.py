import numpy as np
import pytest

from acousim.core.vectors import row_norms


@pytest.mark.parametrize("scale", [1e-9, 1.0, 1e6])
def test_row_norms_are_numpys_to_the_bit(scale):
    rng = np.random.default_rng(7)
    v = rng.standard_normal((50_000, 3)) * rng.uniform(0.01, 100, (50_000, 1)) * scale
    assert np.array_equal(row_norms(v), np.linalg.norm(v, axis=1))
    assert np.array_equal(row_norms(v, keepdims=True), np.linalg.norm(v, axis=1, keepdims=True))


def test_row_norms_of_strided_and_stacked_rows():
    rng = np.random.default_rng(8)
    v = rng.standard_normal((40, 30, 6))[..., ::2]  # not contiguous
    assert np.array_equal(row_norms(v), np.linalg.norm(v, axis=-1))
    assert row_norms(np.array([[3.0, 4.0, 12.0]]))[0] == 13.0
    assert row_norms(np.zeros((0, 3))).shape == (0,)
