"""The compiled means are numpy's to the bit: float32 rows, and float32 rows summed in float64
buffer by buffer (whatever numpy's buffer size), in every layout the detector passes (numpy sums
interleaved rows element after element, others pairwise)."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector.sums import means32, means64

SIZES = [1, 2, 7, 8, 9, 15, 16, 17, 127, 128, 129, 130, 255, 256, 257, 1000, 8191, 8192, 8193, 20000, 70001]


def _rows(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """(1 to 3, n) float32 rows with an offset (centroids far from 0): C, F, strided, gathered by a
    boolean index (interleaved), some of their rows, one row."""
    x = (rng.normal(size=(3, 2 * n)) * rng.uniform(0.001, 1.0) + rng.normal(0.0, 2.0)).astype(np.float32)
    c = np.ascontiguousarray(x[:, :n])
    gathered = x[:, np.arange(2 * n) % 2 == 0]  # rows interleaved, as a boolean index leaves them
    return [c, np.asfortranarray(c[:2]), x[:, ::2], gathered, gathered[:2], c[:1], np.asfortranarray(c)[:1]]


@pytest.mark.parametrize("n", SIZES)
def test_means_are_numpys(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(5):
        for x in _rows(rng, n):
            assert np.array_equal(means32(x), x.mean(axis=1))
            assert np.array_equal(means64(x, np.getbufsize()), x.mean(axis=1, dtype=np.float64))


def test_the_float64_mean_follows_numpys_buffer_size() -> None:
    rng = np.random.default_rng(0)
    x = _rows(rng, 30000)[0]
    old = np.getbufsize()
    try:
        np.setbufsize(4096)
        assert np.array_equal(means64(x, np.getbufsize()), x.mean(axis=1, dtype=np.float64))
    finally:
        np.setbufsize(old)
    assert np.array_equal(means64(x, old), x.mean(axis=1, dtype=np.float64))
