"""The detector's fast pixel-grid helpers give exactly what the general numpy / scipy forms give."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from sofia_detector.pixels import grow, median, shrink, where


@pytest.mark.parametrize("size", [3, 5, 7])
def test_grow_and_shrink_match_the_scipy_filters_at_the_border_too(size: int) -> None:
    rng = np.random.default_rng(size)
    for _ in range(100):
        shape = tuple(int(v) for v in rng.integers(1, 25, 2))
        mask = rng.random(shape) > rng.random()
        as_bytes = mask.view(np.uint8)
        assert np.array_equal(grow(mask, size), ndimage.maximum_filter(as_bytes, size=size).view(bool))
        assert np.array_equal(shrink(mask, size), ndimage.minimum_filter(as_bytes, size=size).view(bool))


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8])
def test_median_is_numpys_median_for_odd_and_even_counts(dtype: type) -> None:
    rng = np.random.default_rng(7)
    for n in range(1, 40):
        samples = (rng.random((n, 3)) * 255).astype(dtype)
        expected = np.median(samples, axis=0)
        got = median(samples)
        assert np.array_equal(got, expected) and got.dtype == expected.dtype
        assert median(samples[:, 0]) == np.median(samples[:, 0])


def test_where_is_nonzero_in_row_major_order() -> None:
    rng = np.random.default_rng(3)
    for shape in [(1, 1), (4, 9), (31, 17)]:
        mask = rng.random(shape) > 0.6
        rows, cols = where(mask)
        ref_rows, ref_cols = np.nonzero(mask)
        assert np.array_equal(rows, ref_rows) and np.array_equal(cols, ref_cols)
    rows, cols = where(np.zeros((3, 4), dtype=bool))
    assert rows.size == 0 and cols.size == 0
