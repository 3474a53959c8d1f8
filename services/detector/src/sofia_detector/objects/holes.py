"""Missing depth on a flat top: pixels of the top's colour joining it on the pixel grid, placed on
its plane by a homography fitted on its pixels with depth; only patches the top or more missing
depth borders (else an oblique side face), never on a board of the top's colour."""

from __future__ import annotations

import cv2
import numpy as np

from ..depth.clean import median_chroma, of_colour
from ..geometry.grid import grow, label8, max_filter, where
from ..geometry.samples import median
from ..segment.points import ObjectPoints

MIN_SHARE = 0.03  # fewer missing pixels of the top's colour than this share of the top: nothing to do
BOARD_LIKE = 0.05  # share of the board around the object of the top's colour above which nothing is done
RAISED = 0.005  # metres above the board: the object, not the board, around the missing pixels
OFF_TOP = 0.2  # largest share of the object's pixels around a missing patch that are off the top
BOARD_SEEN = 0.25  # largest share of a patch's border that is the board with depth
SAMPLE = 400  # top pixels used for the pixel-to-top map
BORDER_PX = 3  # what lies this many pixels around a patch borders it (past the 1-2 px of mixed pixels)


def bordered_patches(grid: np.ndarray, same: np.ndarray, h: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """(h, w) bool: pixels of ``same`` (missing depth of the top's colour) in patches joining the top
    ``grid`` through ``same``, whose border (within :data:`BORDER_PX`; heights h (h, w) float32, NaN
    where missing, metres) above :data:`RAISED` is at most :data:`OFF_TOP` off the top (not in ``grid``
    nor within ``[lo, hi]``) and at most :data:`BOARD_SEEN` the board with depth. A pixel within
    reach of two patches counts for the later-numbered one."""
    labels, n_all = label8(grid | same)
    joined = np.zeros(n_all + 1, dtype=bool)
    joined[labels[grid]] = True
    joined[0] = False
    filled = same & joined[labels]
    parts, n = label8(filled)
    near = max_filter(parts, 2 * BORDER_PX + 1)  # the patch a pixel borders
    border = (near > 0) & ~filled
    k, z = near[border], h[border]
    with np.errstate(invalid="ignore"):
        up = z > RAISED
        off = up & ~grid[border] & ~((lo <= z) & (z <= hi))
        on_board = np.abs(z) < RAISED

    def count(sel: np.ndarray) -> np.ndarray:
        return np.bincount(k[sel], minlength=n + 1)

    good = (count(off) <= OFF_TOP * count(up)) & (
        count(on_board) <= BOARD_SEEN * np.bincount(k, minlength=n + 1)
    )
    good[0] = False
    return good[parts]  # type: ignore[no-any-return]


def unseen_top(obj: ObjectPoints, face: np.ndarray, tol: float) -> np.ndarray:
    """(k, 2) board-frame xy (metres) of the missing depth of the top's colour (within ``tol``) that
    joins the top ``face`` ((n,) bool) (:func:`bordered_patches`); (0, 2) when none."""
    none = np.zeros((0, 2))
    if obj.rgb is None or obj.rows is None or obj.cols is None or obj.window is None:
        return none
    fr, fc = obj.rows[face], obj.cols[face]
    if fr.size < 20:
        return none
    grid = np.zeros(obj.shape, dtype=bool)
    grid[fr, fc] = True
    h = obj.window[2]
    own = median_chroma(obj.rgb, fr[::4], fc[::4])
    missing = np.isnan(h)
    same = np.zeros(grid.shape, dtype=bool)
    same[missing] = of_colour(obj.rgb[missing], own, tol)
    if not (same & grow(grid, 3)).any() or np.count_nonzero(same) < MIN_SHARE * fr.size:
        return none  # too little missing depth of its colour, none next to the top (its stereo shadow)
    with np.errstate(invalid="ignore"):  # the board within four pixels, every second row and column
        board = grow(grid[::2, ::2], 9) & (np.abs(h[::2, ::2]) < RAISED)
    n_board = np.count_nonzero(board)
    if n_board and np.count_nonzero(of_colour(obj.rgb[::2, ::2][board], own, tol)) / n_board > BOARD_LIKE:
        return none  # the object stands on its own colour
    face_h = obj.b[2, face]
    lo, mid = float(face_h.min()), float(median(face_h))
    bordered = bordered_patches(grid, same, h, lo, 2 * mid - lo)
    if np.count_nonzero(bordered) < MIN_SHARE * fr.size:
        return none
    hr, hc = where(bordered)
    k = max(1, fr.size // SAMPLE)
    sr, sc = fr[::k], fc[::k]
    # pixels (col, row) to the top's plane by OpenCV's least-squares homography, in millimetres (in
    # metres it put an edge-cut object's centre 14 mm off on the realistic scenes)
    xy_mm = obj.window[:2, sr, sc].T.astype(np.float64) * 1e3
    H, _ = cv2.findHomography(np.column_stack([sc, sr]).astype(np.float64), xy_mm, 0)
    if H is None:
        return none
    q = np.diag([1e-3, 1e-3, 1.0]) @ H @ np.vstack([hc, hr, np.ones(hr.size)])
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (q[:2] / q[2]).T
    return out[np.isfinite(out).all(axis=1)]  # type: ignore[no-any-return]
