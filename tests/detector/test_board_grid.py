"""The board fit's steps on the coarse grid: the outline of a board top and what lies below it
beside each outline cell, the pixel spacing, and the board outline's side counts."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector.board.fit import _grid_steps, _reach_steps
from sofia_detector.board.grid import board_outline, plane_candidates, reach_hits
from sofia_detector.depth.clean import pixel_spacing


def test_board_outline_of_a_rectangle_with_the_table_on_its_left() -> None:
    """A board top on cells 10..49 x 10..69 of a grid (every second cell taken: 5..24 x 5..34),
    2 mm cells, the table 5 cm below on the left of the board and missing depth elsewhere; an
    object on the board is not in its outline."""
    h, w = 60, 80
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float32)
    m = np.stack([cols * 0.002 - 0.08, rows * 0.002 - 0.06, np.full((h, w), np.nan, np.float32)])
    m[2, 10:50, 10:70] = 0.0
    m[2, 10:50, :10] = -0.05
    m[2, 30:34, 30:34] = 0.03  # an object
    xy, A, hits = board_outline(m.astype(np.float32), 0.008, 1.0, 1.0, _reach_steps(2))
    r, c = A[:, 0].astype(int), A[:, 1].astype(int)
    assert r.min() == 5 and r.max() == 24 and c.min() == 5 and c.max() == 34
    on_edge = (r == 5) | (r == 24) | (c == 5) | (c == 34)
    assert on_edge.all()
    assert np.allclose(xy, m[:2, 2 * r, 2 * c].T)
    assert np.allclose(_grid_steps(A), [[0.0, 0.004], [0.004, 0.0]], atol=1e-6)  # a row moves y
    left = hits[:, 6:8].any(axis=1)  # the table 1-2 cells to the left
    assert np.array_equal(left, c <= 6) and hits[c == 5, 6].all()
    assert not hits[:, :6].any()  # down, up, right: nothing lower


def test_plane_candidates_within_the_limits_every_kth() -> None:
    rng = np.random.default_rng(0)
    q = rng.normal(0.0, 0.3, (3, 20000)).astype(np.float32)
    q[:, rng.random(20000) < 0.2] = np.nan
    got = plane_candidates(q, 0.28, 0.2, 0.05, 100)
    assert 100 <= got.shape[1] <= 200
    assert np.all(np.abs(got[0]) < 0.28) and np.all(np.abs(got[1]) < 0.2) and np.all(np.abs(got[2]) < 0.05)


def test_reach_hits_off_the_grid_are_false() -> None:
    low = np.ones((3, 3), dtype=bool)
    hits = reach_hits(low, np.array([0, 1]), np.array([0, 1]), _reach_steps(2))
    # (0, 0): down 1, 2 on the grid, up off it, right 1, 2 on it, left off it
    assert hits[0].tolist() == [True, True, False, False, True, True, False, False]
    assert hits[1].tolist() == [True, False, True, False, True, False, True, False]


def test_pixel_spacing_is_the_numpy_median() -> None:
    rng = np.random.default_rng(3)
    for _ in range(300):
        h, w = int(rng.integers(1, 130)), int(rng.integers(1, 170))
        m = (rng.normal(size=(3, h, w)) * rng.choice([1e-3, 1.0])).astype(np.float32)
        m[rng.random(m.shape) < rng.random() * 0.5] = np.nan
        step = m[:, ::8, 1:] - m[:, ::8, :-1]
        d = np.sqrt(np.einsum("kij,kij->ij", step, step)).ravel()
        d = d[np.isfinite(d)]
        want = float(np.median(d)) / 4 if d.size else 0.0012
        assert pixel_spacing(m, 4) == pytest.approx(want, rel=1e-6)
