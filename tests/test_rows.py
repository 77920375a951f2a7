"""The column-by-column reductions equal NumPy's to the bit."""

import numpy as np
import pytest

from o3d_spectral.io.rows import bounds, every, largest_side, lengths, some


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_reductions_equal_numpys_to_the_bit(dtype):
    x = np.random.default_rng(0).normal(size=(5000, 3)).astype(dtype)
    lower, upper = bounds(x)
    np.testing.assert_array_equal(lower, x.min(axis=0))
    np.testing.assert_array_equal(upper, x.max(axis=0))
    assert lower.dtype == x.dtype
    assert largest_side(x) == float(np.max(np.ptp(x, axis=0)))
    np.testing.assert_array_equal(lengths(x), np.linalg.norm(x, axis=1))
    mask = x > 0.5
    np.testing.assert_array_equal(every(mask), np.all(mask, axis=1))
    np.testing.assert_array_equal(some(mask), np.any(mask, axis=1))


def test_bounds_of_integer_keys_and_of_a_nan_column():
    keys = np.random.default_rng(1).integers(-50, 50, size=(300, 3))
    np.testing.assert_array_equal(bounds(keys)[1], keys.max(axis=0))
    x = np.ones((4, 3))
    x[2, 1] = np.nan
    lower, upper = bounds(x)
    assert np.isnan(lower[1]) and np.isnan(upper[1])  # as numpy: NaN propagates
