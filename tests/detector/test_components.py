"""The pixel-grid helpers (OpenCV underneath) keep SciPy's conventions: 8-connected components,
squares that ignore the pixels outside the image; the grid boundary and the plane fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from sofia_detector.board.plane import fit_plane
from sofia_detector.geometry.grid import (
    boundary_points,
    grid_boundary,
    grow,
    label8,
    label_sizes,
    largest_component,
    max_filter,
    shrink,
    where,
)

EIGHT = np.ones((3, 3), dtype=bool)


def _masks(seed: int, n: int) -> list[np.ndarray]:
    """Random masks from sparse specks to solid blobs, one row or column thin to 60 x 60."""
    rng = np.random.default_rng(seed)
    out = [np.zeros((5, 7), bool), np.ones((4, 3), bool), np.eye(9, dtype=bool), np.eye(9, dtype=bool)[::-1]]
    for k in range(n):
        shape = (int(rng.integers(1, 60)), int(rng.integers(1, 60)))
        mask = rng.random(shape) > rng.uniform(0.05, 0.95)
        out.append(ndimage.binary_dilation(mask, iterations=int(rng.integers(1, 4))) if k % 3 == 0 else mask)
    return out


def _same_partition(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two labellings (h, w) int split the pixels alike (0 off every label in both)."""
    pairs = np.unique(np.stack([a.ravel(), b.ravel()]), axis=1)
    return bool(np.array_equal(a == 0, b == 0) and len(set(pairs[0])) == len(set(pairs[1])) == pairs.shape[1])


def test_label8_splits_the_pixels_as_scipy_does() -> None:
    for mask in _masks(0, 300):
        expected, n = ndimage.label(mask, structure=EIGHT)
        got, m = label8(mask)
        assert m == n and _same_partition(got, expected)
        labels, k, sizes = label_sizes(mask)
        assert k == n and np.array_equal(labels, got)
        assert sizes[0] == np.count_nonzero(~mask)
        assert sorted(sizes[1:]) == sorted(np.bincount(expected.ravel(), minlength=n + 1)[1:])
        if n:
            assert np.array_equal(largest_component(mask), got == 1 + np.argmax(sizes[1:]))
        else:
            assert not largest_component(mask).any()


def test_label8_joins_a_u_shape_met_from_both_arms() -> None:
    u = np.zeros((5, 7), bool)
    u[0:4, 1] = u[0:4, 5] = u[4, 1:6] = True  # two arms met first as two labels, joined at the bottom
    labels, n = label8(u)
    assert n == 1 and set(np.unique(labels[u])) == {1}


def test_filters_are_scipys() -> None:
    for mask in _masks(1, 300):
        labels, _ = ndimage.label(mask, structure=EIGHT)
        for size in (3, 7):
            assert np.array_equal(max_filter(labels, size), ndimage.maximum_filter(labels, size=size))
            as_bytes = mask.view(np.uint8)  # the image border neither grows nor erodes a mask
            assert np.array_equal(grow(mask, size), ndimage.maximum_filter(as_bytes, size=size).view(bool))
            assert np.array_equal(shrink(mask, size), ndimage.minimum_filter(as_bytes, size=size).view(bool))


def test_where_is_nonzero_in_row_major_order() -> None:
    for mask in _masks(4, 20):
        rows, cols = where(mask)
        ref_rows, ref_cols = np.nonzero(mask)
        assert np.array_equal(rows, ref_rows) and np.array_equal(cols, ref_cols)


def test_grid_boundary_is_the_first_and_last_cell_of_every_row_and_column() -> None:
    """Of a mask, and of its pixels given by index in any order (:func:`boundary_points`), all of
    them or a subset."""
    rng = np.random.default_rng(2)
    for mask in _masks(2, 200):
        rows, cols = grid_boundary(mask)
        r_any, c_any = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
        h, w = mask.shape
        ref_rows = np.concatenate(
            [r_any, r_any, np.argmax(mask, axis=0)[c_any], h - 1 - np.argmax(mask[::-1], axis=0)[c_any]]
        )
        ref_cols = np.concatenate(
            [np.argmax(mask, axis=1)[r_any], w - 1 - np.argmax(mask[:, ::-1], axis=1)[r_any], c_any, c_any]
        )
        assert np.array_equal(rows, ref_rows) and np.array_equal(cols, ref_cols)
        r, c = np.nonzero(mask)
        order = rng.permutation(r.size)
        at = boundary_points(r[order], c[order], (h, w))
        assert np.array_equal(r[order][at], ref_rows) and np.array_equal(c[order][at], ref_cols)
        # a subset of the pixels: indices into all of them, the points of the gathered subset's
        subset = rng.random(r.size) < 0.6
        ro, co = r[order], c[order]
        at = boundary_points(ro, co, (h, w), subset)
        want = boundary_points(ro[subset], co[subset], (h, w))
        assert np.array_equal(at, np.flatnonzero(subset)[want])


def test_plane_fit_drops_what_stands_on_it_and_refuses_a_line() -> None:
    rng = np.random.default_rng(4)
    x, y = rng.uniform(-0.3, 0.3, 3000), rng.uniform(-0.2, 0.2, 3000)
    z = 0.01 + 0.02 * x - 0.01 * y + rng.normal(0, 0.001, x.size)
    z[:400] += rng.uniform(0.02, 0.1, 400)  # objects on the board
    fit = fit_plane(*(v.astype(np.float32) for v in (x, y, z)), (0.025, 0.01, 0.006), 50)
    assert fit is not None
    assert np.allclose(fit.coef, (0.01, 0.02, -0.01), atol=6e-4)  # ~3.5 standard errors of a slope
    assert fit.rms == pytest.approx(0.001, rel=0.15) and 2400 <= fit.n_inliers <= 2600
    on_a_line = np.linspace(-0.2, 0.2, 100, dtype=np.float32)
    assert fit_plane(on_a_line, 2 * on_a_line, np.zeros_like(on_a_line), (0.01,), 50) is None
