"""The board fit's steps: plane candidates, the board top's outline on an occupancy grid in the plane."""

from __future__ import annotations

import numpy as np

from ..geometry.grid import grid_boundary, largest_component

CELL = 0.008  # occupancy cell of the outline, metres
REACH = 5  # cells from the board top to the surface below its edge: the strip of table its side hides
STEPS = np.concatenate([np.outer(np.arange(1, REACH + 1), s) for s in ((1, 0), (-1, 0), (0, 1), (0, -1))])


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


def outline_points(m: np.ndarray, band: float, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2) plane-frame points on the board top's outline and the direction (not normalised) from
    each towards the cells below the top it reaches (0 where missing depth, the image border or
    something in front cuts the top short). m: (3, n) float32, plane frame, metres, NaN allowed. The
    top: the largest patch of points within ``band`` of the plane and ``half`` (2,) of its centre on
    a grid of :data:`CELL`; below it: lower than ``-band``, up to :data:`REACH` cells out."""
    with np.errstate(invalid="ignore"):
        inside = (np.abs(m[0]) < half[0]) & (np.abs(m[1]) < half[1])
        top, low = inside & (np.abs(m[2]) < band), inside & (m[2] < -band)
    shape = tuple(np.ceil(2 * half / CELL).astype(int) + 1)

    def occupancy(sel: np.ndarray) -> np.ndarray:
        idx = np.floor((m[:2, sel].T + half) / CELL).astype(np.intp)
        occ = np.zeros(shape, dtype=bool)
        occ[idx[:, 0], idx[:, 1]] = True
        return occ

    comp = largest_component(occupancy(top))
    if not comp.any():
        return np.empty((0, 2)), np.empty((0, 2))
    r, c = grid_boundary(comp)
    xy = (np.stack([r, c], axis=1) + 0.5) * CELL - half
    return xy, reach_hits(occupancy(low), r, c, STEPS) @ (CELL * STEPS)
