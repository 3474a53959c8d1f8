"""The board fit's steps on the coarse grid: plane candidates, the board top's outline."""

from __future__ import annotations

import numpy as np

from ..geometry.grid import grid_boundary, largest_component


def plane_candidates(q: np.ndarray, lim_x: float, lim_y: float, band: float, max_points: int) -> np.ndarray:
    """(3, k) float32: every ``max(1, count // max_points)``-th point of q (3, n) float32 (configured
    board frame, metres, NaN allowed) with ``|x| < lim_x``, ``|y| < lim_y``, ``|z| < band``."""
    with np.errstate(invalid="ignore"):
        at = np.flatnonzero((np.abs(q[0]) < lim_x) & (np.abs(q[1]) < lim_y) & (np.abs(q[2]) < band))
    return q[:, at[:: max(1, at.size // max_points)]]  # type: ignore[no-any-return]


def reach_hits(low: np.ndarray, r: np.ndarray, c: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """(k, s) bool: ``low`` (h, w) bool at each of the ``steps`` (s, 2) int (row, column) from each
    cell ``(r, c)`` (k,); False off the grid."""
    rr, cc = r[:, None] + steps[:, 0], c[:, None] + steps[:, 1]
    on = (rr >= 0) & (rr < low.shape[0]) & (cc >= 0) & (cc < low.shape[1])
    hits = np.zeros(rr.shape, dtype=bool)
    hits[on] = low[rr[on], cc[on]]
    return hits


def board_outline(
    m: np.ndarray, band: float, half_x: float, half_y: float, steps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The board top's outline on every second cell of m (3, h, w) float32 (plane frame, metres):
    the top, cells within ``band`` of the plane and ``half_x``, ``half_y`` of its centre; below it,
    cells lower than ``-band``. Returns (k, 2) float32 points at the :func:`grid_boundary` of the
    top's largest patch, (k, 5) float64 rows ``(row, col, 1, x, y)`` and (k, s) :func:`reach_hits`
    of the cells below at ``steps`` (s, 2)."""
    x, y, z = m[:, ::2, ::2]
    with np.errstate(invalid="ignore"):
        top = (np.abs(z) < band) & (np.abs(x) < half_x) & (np.abs(y) < half_y)
        low = z < -band
    rows, cols = grid_boundary(largest_component(top))
    xy = np.stack([x[rows, cols], y[rows, cols]], axis=1)
    A = np.column_stack([rows, cols, np.ones(rows.size), xy]).astype(np.float64)
    return xy, A, reach_hits(low, rows, cols, steps)
