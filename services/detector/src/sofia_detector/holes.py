"""Missing depth on a flat top, placed on the top from its colour.

A stereo camera returns no depth on dark or glossy patches, and none where the second imager's
view is blocked (the fingers' shadow). The colour camera still sees those pixels. Where they
have the top's colour and join the top on the pixel grid, they are the top: the top is a plane,
so the pixel grid maps onto it smoothly (a homography, close to a quadratic over one object),
and the map fitted on the top's pixels with depth places the others. This is done only where
the board around the object has another colour (on a field of its own colour, the board's
missing depth, the object's stereo shadow, could not be told apart from the top), and where the
object's pixels with depth around the missing ones are on the top (not a cone's flank or a
side: those are not on the top's plane).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .depth_clean import EIGHT, chroma, colour_distance
from .pixels import grow, median, where
from .segment import ObjectPoints

MIN_SHARE = 0.03  # fewer missing pixels of the top's colour than this share of the top: nothing to do
BOARD_LIKE = 0.05  # share of the board around the object of the top's colour above which nothing is done
RAISED = 0.005  # metres above the board: the object, not the board, around the missing pixels
OFF_TOP = 0.2  # largest share of the object's pixels around a missing patch that are off the top
SAMPLE = 400  # top pixels used for the pixel-to-top map


def _terms(r: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(n, 6) quadratic terms of pixel coordinates (n,) (centred and scaled by the caller)."""
    return np.column_stack([np.ones_like(r), r, c, r * r, r * c, c * c])


def unseen_top(obj: ObjectPoints, face: np.ndarray, tol: float) -> np.ndarray:
    """(k, 2) board-frame xy (metres) of the missing-depth pixels of the top's colour that join the
    top ``face`` ((n,) bool over the object's points) on the pixel grid; (0, 2) when there are
    none, no colours, or the board around has the top's colour. tol: colour distance
    (:func:`.depth_clean.colour_distance` of :func:`.depth_clean.chroma`)."""
    none = np.zeros((0, 2))
    if obj.rgb is None or obj.rows is None or obj.cols is None or obj.window is None:
        return none
    fr, fc = obj.rows[face], obj.cols[face]
    if fr.size < 20:
        return none
    grid = np.zeros(obj.shape, dtype=bool)
    grid[fr, fc] = True
    h = obj.window[2]
    missing = np.isnan(h)
    a_r, a_c = where(missing & grow(grid, 3))  # missing pixels next to the top
    if a_r.size == 0:
        return none
    own = chroma(median(obj.rgb[fr[::4], fc[::4]].astype(np.float64)))
    if not (colour_distance(chroma(obj.rgb[a_r, a_c]), own) < tol).any():
        return none  # none of the top's colour (the board in the object's stereo shadow)
    m_r, m_c = where(missing)
    same = np.zeros_like(missing)
    same[m_r, m_c] = colour_distance(chroma(obj.rgb[m_r, m_c]), own) < tol
    if np.count_nonzero(same) < MIN_SHARE * fr.size:
        return none
    with np.errstate(invalid="ignore"):
        board = (np.abs(h[::2, ::2]) < 0.005) & grow(grid[::2, ::2], 9)
    b_r, b_c = where(board)
    b_r, b_c = 2 * b_r, 2 * b_c
    if b_r.size and np.mean(colour_distance(chroma(obj.rgb[b_r, b_c]), own) < tol) > BOARD_LIKE:
        return none  # the object stands on its own colour
    labels, _ = ndimage.label(grid | same, structure=EIGHT)
    joined = np.zeros(labels.max() + 1, dtype=bool)
    joined[labels[fr, fc]] = True
    joined[0] = False
    filled = same & joined[labels]
    # each patch of them: the object's pixels with depth around it must be on the top (not on a
    # cone's flank or a side, which do not lie in the top's plane)
    parts, n = ndimage.label(filled, structure=EIGHT)
    near = ndimage.maximum_filter(parts, size=3)  # the patch a pixel borders
    with np.errstate(invalid="ignore"):
        raised = (near > 0) & ~filled & (h > RAISED)
    total = np.bincount(near[raised], minlength=n + 1)
    off = np.bincount(near[raised & ~grid], minlength=n + 1)
    good = off <= OFF_TOP * total
    good[0] = False
    hr, hc = where(good[parts])
    if hr.size < MIN_SHARE * fr.size:
        return none
    k = max(1, fr.size // SAMPLE)
    sr, sc = fr[::k], fc[::k]
    xy = obj.window[:2, sr, sc].T.astype(np.float64)
    m = np.array([sr.mean(), sc.mean()])
    scale = max(float(np.ptp(sr)), float(np.ptp(sc)), 1.0)
    A = _terms((sr - m[0]) / scale, (sc - m[1]) / scale)
    coef, *_ = np.linalg.lstsq(A, xy, rcond=None)
    out = _terms((hr - m[0]) / scale, (hc - m[1]) / scale) @ coef
    return out[np.isfinite(out).all(axis=1)]  # type: ignore[no-any-return]
