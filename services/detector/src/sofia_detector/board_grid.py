"""The board fit's steps on the coarse grid, compiled (numba): its plane candidates, and the outline
of an organized cloud's board top with what lies below it beside each outline cell.

Each is one pass over a few thousand cells that numpy ran as a dozen calls (masks, ``flatnonzero``,
gathers, labels, the largest label, row and column extremes, stacking), each costing more to set
up than its arithmetic. They give the arrays the numpy steps gave, bit for bit: thresholds that a
Python float sets compare in float32 (numpy casts a Python float to the array's float32), the
outline's half size in float64 (a numpy float64 scalar).
"""

from __future__ import annotations

import numpy as np

from .components import label8_jit, largest_label
from .kernels import jit
from .outline import boundary_points


@jit
def plane_candidates(
    q: np.ndarray, lim_x: np.float32, lim_y: np.float32, band: np.float32, max_points: int
) -> np.ndarray:
    """(3, k) float32 points of ``q`` (3, n) float32 (configured board frame, metres, NaN allowed)
    with ``|x| < lim_x``, ``|y| < lim_y`` and ``|z| < band``, every ``max(1, count // max_points)``-th
    of them in order: ``q[:, flatnonzero(cand)[::step]]``."""
    n = q.shape[1]
    cand = np.zeros(n, dtype=np.bool_)
    count = 0
    for i in range(n):
        if abs(q[0, i]) < lim_x and abs(q[1, i]) < lim_y and abs(q[2, i]) < band:
            cand[i] = True
            count += 1
    step = max(1, count // max_points)
    out = np.empty((3, (count + step - 1) // step), dtype=np.float32)
    seen, k = 0, 0
    for i in range(n):
        if cand[i]:
            if seen % step == 0:
                out[0, k], out[1, k], out[2, k] = q[0, i], q[1, i], q[2, i]
                k += 1
            seen += 1
    return out


@jit
def reach_hits(low: np.ndarray, r: np.ndarray, c: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """(k, s) bool: whether ``low`` (h, w) bool is set at each of the ``steps`` (s, 2) int (row,
    column) from each cell ``(r, c)`` (k,) (:func:`.board_fit._reach_steps`); False off the grid."""
    h, w = low.shape
    hits = np.zeros((r.size, steps.shape[0]), dtype=np.bool_)
    for i in range(r.size):
        for j in range(steps.shape[0]):
            rr, cc = r[i] + steps[j, 0], c[i] + steps[j, 1]
            if 0 <= rr < h and 0 <= cc < w:
                hits[i, j] = low[rr, cc]
    return hits


@jit
def board_outline(
    m: np.ndarray, band: np.float32, half_x: float, half_y: float, steps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The outline of the board top on every second cell of an organized coarse grid.

    m: (3, h, w) float32, plane frame, metres, NaN allowed. The board top: cells within ``band`` of
    the plane (float32), within ``half_x``, ``half_y`` of its centre (float64); below it: cells
    lower than ``-band``. Returns (k, 2) float32 plane-frame points at :func:`.outline.grid_boundary`
    of the top's largest 8-connected patch, (k, 5) float64 rows ``(row, col, 1, x, y)`` of those
    cells (for the grid-step fit), and (k, s) bool :func:`reach_hits` of the cells below the top at
    ``steps`` (s, 2) from each; k is 0 when no cell is on the top.
    """
    h, w = (m.shape[1] + 1) // 2, (m.shape[2] + 1) // 2
    top = np.zeros((h, w), dtype=np.bool_)
    low = np.zeros((h, w), dtype=np.bool_)
    for r in range(h):
        for c in range(w):
            x, y, z = m[0, 2 * r, 2 * c], m[1, 2 * r, 2 * c], m[2, 2 * r, 2 * c]
            top[r, c] = abs(z) < band and abs(np.float64(x)) < half_x and abs(np.float64(y)) < half_y
            low[r, c] = z < -band
    labels, n = label8_jit(top)
    keep, count = largest_label(labels, n)  # the largest patch
    rows, cols = np.empty(count, dtype=np.int64), np.empty(count, dtype=np.int64)
    k = 0
    for r in range(h):  # the patch's cells in row-major order, as np.nonzero lists them
        for c in range(w):
            if labels[r, c] == keep:
                rows[k], cols[k] = r, c
                k += 1
    at = boundary_points(rows, cols, h, w)
    rows, cols = rows[at], cols[at]
    xy = np.empty((rows.size, 2), dtype=np.float32)
    A = np.empty((rows.size, 5))
    for i in range(rows.size):
        xy[i, 0], xy[i, 1] = m[0, 2 * rows[i], 2 * cols[i]], m[1, 2 * rows[i], 2 * cols[i]]
        A[i, 0], A[i, 1], A[i, 2], A[i, 3], A[i, 4] = rows[i], cols[i], 1.0, xy[i, 0], xy[i, 1]
    return xy, A, reach_hits(low, rows, cols, steps)
