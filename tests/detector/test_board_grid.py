"""The board fit's compiled grid steps give exactly what the numpy steps they replace gave: the same
plane candidates, outline cells, points, grid-step rows and drops, and the same pixel spacing, on
random grids with missing depth, values on the thresholds, and no board at all; and the board
outline's side counts."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector.board_fit import EDGE_REACH_PX, _reach_steps
from sofia_detector.board_grid import board_outline, plane_candidates, reach_hits
from sofia_detector.depth_clean import pixel_spacing
from sofia_detector.outline import _side_counts, grid_boundary, largest_component
from sofia_detector.pixels import median


def _grids(seed: int, n: int) -> list[np.ndarray]:
    """(3, h, w) float32 coarse grids: a board top at height ~0 with objects on it, the table below
    beside it, missing depth, odd and even sizes, and some values exactly on the thresholds."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        h, w = int(rng.integers(1, 70)), int(rng.integers(1, 90))
        x, y = np.meshgrid(np.linspace(-0.4, 0.4, w), np.linspace(-0.3, 0.3, h))
        z = rng.normal(0.0, 0.004, (h, w))
        z[rng.random((h, w)) < 0.1] = 0.03  # objects
        z[np.abs(x) > rng.uniform(0.2, 0.45)] = -0.05  # the table beside the board
        m = np.stack([x, y, z]).astype(np.float32)
        m[:, rng.random((h, w)) < rng.uniform(0.0, 0.5)] = np.nan
        m[2, rng.random((h, w)) < 0.05] = np.float32(0.008)  # on the band's threshold
        m[0, rng.random((h, w)) < 0.05] = np.float32(0.3)  # on the half size's threshold
        out.append(m)
    out.append(np.full((3, 8, 9), np.nan, dtype=np.float32))  # no board
    return out


def _numpy_outline(m: np.ndarray, band: float, half: np.ndarray, reach: int):  # type: ignore[no-untyped-def]
    """The numpy steps: masks on every second cell, the largest patch, its row and column extremes,
    their points, the grid-step rows and the cells below the top within reach."""
    sub = m[:, ::2, ::2]
    with np.errstate(invalid="ignore"):
        top = (np.abs(sub[2]) < band) & (np.abs(sub[0]) < half[0]) & (np.abs(sub[1]) < half[1])
        low = sub[2] < -band
    comp = largest_component(top)
    if not comp.any():
        return None
    r, c = grid_boundary(comp)
    xy = np.stack([sub[0, r, c], sub[1, r, c]], axis=1)
    A = np.column_stack((r, c, np.ones(r.size), xy))
    h, w = low.shape
    padded = np.zeros((h + 2 * reach, w + 2 * reach), dtype=bool)
    padded[reach : reach + h, reach : reach + w] = low
    drc = _reach_steps(reach)
    hits = padded[r[:, None] + (drc[:, 0] + reach), c[:, None] + (drc[:, 1] + reach)]
    return xy, A, hits


@pytest.mark.parametrize("seed", range(6))
def test_board_outline_is_the_numpy_steps(seed: int) -> None:
    half = np.array([0.3, 0.25]) + 0.0  # numpy float64, as the board fit passes it
    for m in _grids(seed, 25):
        for reach in (1, EDGE_REACH_PX, 5):
            xy, A, hits = board_outline(m, np.float32(0.008), half[0], half[1], _reach_steps(reach))
            want = _numpy_outline(m, 0.008, half, reach)
            if want is None:
                assert xy.shape == (0, 2) and A.shape == (0, 5) and hits.shape == (0, 4 * reach)
                continue
            assert xy.dtype == want[0].dtype and np.array_equal(xy, want[0])
            assert np.array_equal(A, want[1])
            assert np.array_equal(hits, want[2])
            drops = hits @ (_reach_steps(reach) @ np.eye(2).T)
            assert drops.shape == (xy.shape[0], 2)


def test_reach_hits_off_the_grid_are_false() -> None:
    low = np.ones((3, 3), dtype=bool)
    hits = reach_hits(low, np.array([0, 1]), np.array([0, 1]), _reach_steps(2))
    # (0, 0): down 1, 2 on the grid, up off it, right 1, 2 on it, left off it
    assert hits[0].tolist() == [True, True, False, False, True, True, False, False]
    assert hits[1].tolist() == [True, False, True, False, True, False, True, False]


@pytest.mark.parametrize("seed", range(4))
def test_plane_candidates_are_the_numpy_gather(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for n in (0, 1, 50, 3000, 20000):
        q = rng.normal(0.0, 0.3, (3, n)).astype(np.float32)
        q[:, rng.random(n) < 0.2] = np.nan
        q[0, rng.random(n) < 0.05] = np.float32(0.28)  # on the threshold
        for max_points in (1, 7, 2500, 50000):
            lim_x, lim_y, band = 0.28, 0.2, 0.05
            got = plane_candidates(q, np.float32(lim_x), np.float32(lim_y), np.float32(band), max_points)
            with np.errstate(invalid="ignore"):
                cand = (np.abs(q[0]) < lim_x) & (np.abs(q[1]) < lim_y) & (np.abs(q[2]) < band)
            idx = np.flatnonzero(cand)
            want = q[:, idx[:: max(1, idx.size // max_points)]]
            assert got.dtype == np.float32 and np.array_equal(got, want, equal_nan=True)


def test_pixel_spacing_is_the_numpy_median() -> None:
    rng = np.random.default_rng(3)
    for _ in range(300):
        h, w = int(rng.integers(1, 130)), int(rng.integers(1, 170))
        m = (rng.normal(size=(3, h, w)) * rng.choice([1e-3, 1.0])).astype(np.float32)
        m[rng.random(m.shape) < rng.random() * 0.5] = np.nan
        step = m[:, ::8, 1:] - m[:, ::8, :-1]
        d = np.sqrt(np.einsum("kij,kij->ij", step, step)).ravel()
        d = d[np.isfinite(d)]
        want = float(median(d)) / 4 if d.size else 0.0012
        assert pixel_spacing(m, 4) == want


def test_side_counts_are_the_numpy_form() -> None:
    """The board outline's sides: the points near each side and those of them dropping outwards,
    as the numpy steps counted them, on blobs and pixel-grid outlines (many points on a side)."""
    rng = np.random.default_rng(1)
    for _ in range(500):
        k = int(rng.integers(1, 400))
        xy = rng.normal(size=(k, 2)) * rng.uniform(0.01, 0.5)
        if rng.random() < 0.5:
            xy = np.round(xy / 0.004) * 0.004
        yaw = rng.uniform(-0.8, 0.8)
        R = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        drop = rng.normal(size=(k, 2))
        drop[rng.random(k) < 0.4] = 0.0
        for d_xy in (drop, None):
            u = R.T @ xy.T
            beyond = np.concatenate([-u, u])
            near = beyond >= beyond.max(axis=1, keepdims=True) - 0.015
            out = near
            if d_xy is not None:
                d = R.T @ d_xy.T
                out = near & (np.concatenate([-d, d]) > 0.5 * np.hypot(d[0], d[1]))
            n_near, n_out = _side_counts(xy, d_xy, R, 0.015)
            assert n_near.tolist() == np.count_nonzero(near, axis=1).tolist()
            assert n_out.tolist() == np.count_nonzero(out, axis=1).tolist()
