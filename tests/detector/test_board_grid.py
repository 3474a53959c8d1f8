"""The board fit's steps: the outline of a board top and what lies below it beside each outline
cell, plane candidates, the pixel spacing."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector.board.grid import CELL, STEPS, outline_points, plane_candidates, reach_hits
from sofia_detector.depth.clean import pixel_spacing


def test_outline_of_a_board_top_with_the_table_on_its_left() -> None:
    """A board top 0.40 x 0.30 m seen every 2 mm (plane frame), the table 5 cm below on its left
    (-x), missing depth elsewhere, an object in its middle: the outline lies on the top's edges, only
    its left side drops towards -x, the object is not in it."""
    x, y = np.meshgrid(np.arange(-0.26, 0.26, 0.002), np.arange(-0.2, 0.2, 0.002), indexing="ij")
    z = np.full(x.shape, np.nan)
    on = (np.abs(x) < 0.2) & (np.abs(y) < 0.15)
    z[on] = 0.0
    z[(x < -0.2) & (np.abs(y) < 0.15)] = -0.05
    z[(np.abs(x) < 0.03) & (np.abs(y) < 0.03)] = 0.03  # an object
    m = np.stack([x, y, z]).reshape(3, -1).astype(np.float32)
    xy, drop = outline_points(m, 0.008, np.array([0.28, 0.22]))
    edge = np.minimum(0.2 - np.abs(xy[:, 0]), 0.15 - np.abs(xy[:, 1]))
    assert xy.shape[0] > 50 and np.all(edge < CELL) and np.all(edge > -CELL)  # on the top's edges
    left = xy[:, 0] < -0.2 + CELL
    assert np.all(drop[left, 0] < 0) and np.all(drop[~left & (np.abs(xy[:, 1]) < 0.15 - CELL)] == 0)
    assert outline_points(m[:, :0], 0.008, np.array([0.28, 0.22]))[0].shape == (0, 2)  # nothing seen


def test_plane_candidates_within_the_limits_every_kth() -> None:
    rng = np.random.default_rng(0)
    q = rng.normal(0.0, 0.3, (3, 20000)).astype(np.float32)
    q[:, rng.random(20000) < 0.2] = np.nan
    got = plane_candidates(q, 0.28, 0.2, 0.05, 100)
    assert 100 <= got.shape[1] <= 200
    assert np.all(np.abs(got[0]) < 0.28) and np.all(np.abs(got[1]) < 0.2) and np.all(np.abs(got[2]) < 0.05)


def test_reach_hits_off_the_grid_are_false() -> None:
    low = np.ones((3, 3), dtype=bool)
    hits = reach_hits(low, np.array([0, 1]), np.array([0, 1]), STEPS[[0, 1, 5, 6, 10, 11, 15, 16]])
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
