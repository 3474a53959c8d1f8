"""Objects of an organized cloud: seeds on the coarse pixel grid (heights above the measured
plane), then full resolution only inside each seed's pixel window."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from scipy import ndimage

from ..depth import raised_pixels
from ..geometry.grid import where
from ..geometry.points import points_in_frame
from ..geometry.samples import median
from ..params import DetectorParams
from .points import Levels, ObjectPoints, inside

MIN_PART = 10  # pixels of the smallest part standing on an object that is joined to it
PART_MARGIN = 0.005  # metres


def organized_objects(
    points_base: np.ndarray,
    m_coarse: np.ndarray,
    T_base_board: np.ndarray,
    T_board_plane: np.ndarray,
    half: np.ndarray,
    params: DetectorParams,
    levels: Levels,
    rgb: np.ndarray | None = None,
) -> Iterator[ObjectPoints]:
    """Objects of points_base (H, W, 3) float, base frame, metres. m_coarse: (3, h, w) float32,
    ``points_base[::stride, ::stride]`` in the plane frame. T_base_board, T_board_plane: (4, 4).
    half: (2,) half size of the region of object centres, board frame. rgb: (H, W, 3) uint8 or None.
    """
    s = params.stride
    H, W = points_base.shape[:2]
    rgb_coarse = None if rgb is None else rgb[::s, ::s]
    raised = raised_pixels(
        m_coarse, levels.seed, params.max_height, levels.delta_coarse, rgb_coarse, params.colour_tol
    )
    seeds, labels, n = raised.mask, raised.labels, raised.n
    claimed = np.zeros((H, W), dtype=bool)  # the pixels of the objects found so far
    pad = 2
    for i, sl in enumerate(ndimage.find_objects(labels, max_label=n), start=1):
        if sl is None:
            continue
        comp = (labels[sl] == i) & seeds[sl]
        sr, sc = where(comp)
        if sr.size < params.min_seed_pixels:
            continue
        xy_plane = m_coarse[:2][:, sl[0], sl[1]][:, comp].mean(axis=1)
        if not inside(T_board_plane[:2, :2] @ xy_plane + T_board_plane[:2, 3], half):
            continue  # clutter beside the board
        rows, cols = (sr + sl[0].start) * s, (sc + sl[1].start) * s  # full-resolution seed pixels
        if claimed[rows, cols].any():
            continue  # a second seed of an object already found (holes in the cloud split it)
        r0, r1 = max((sl[0].start - pad) * s, 0), min((sl[0].stop + pad) * s, H)
        c0, c1 = max((sl[1].start - pad) * s, 0), min((sl[1].stop + pad) * s, W)
        b = points_in_frame(points_base[r0:r1, c0:c1], T_base_board)
        window = raised_pixels(b, levels.point, params.max_height, levels.delta)
        wl, n_pieces = window.labels, window.n
        hits = wl[rows - r0, cols - c0]
        hits = hits[hits > 0]
        if hits.size == 0:
            continue
        counts = np.bincount(hits)
        pieces = np.flatnonzero(counts >= max(2.0, 0.1 * counts.max()))
        if pieces.size == 0:
            continue  # no piece holds two seed hits: specks, no object
        obj = np.isin(wl, pieces) if pieces.size > 1 else wl == pieces[0]
        if n_pieces > pieces.size:
            obj = _with_parts_on_top(wl, n_pieces, b, obj, pieces)
        claimed[r0:r1, c0:c1] |= obj
        rows_obj, cols_obj = where(obj)
        yield ObjectPoints(
            b[:, rows_obj, cols_obj], rows_obj, cols_obj, obj.shape, (r0, c0), (H, W), b,
            None if rgb is None else rgb[r0:r1, c0:c1],
        )  # fmt: skip


def _with_parts_on_top(
    labels: np.ndarray, n: int, b: np.ndarray, obj: np.ndarray, pieces: np.ndarray
) -> np.ndarray:
    """``obj`` (h, w) bool (the ``pieces`` of ``labels`` (h, w), 1..n) with the other pieces that
    stand on it (a bottle's neck above its shoulder, cut off by a step in depth): at least
    :data:`MIN_PART` pixels, above its median point, within its bounding box (+ :data:`PART_MARGIN`).
    b: (3, h, w) board-frame coordinates of the window, metres."""
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    sizes[pieces] = 0
    sizes[0] = 0
    parts = np.flatnonzero(sizes >= MIN_PART)
    if parts.size == 0:
        return obj
    xy = b[:2, obj]
    lo, hi = xy.min(axis=1) - PART_MARGIN, xy.max(axis=1) + PART_MARGIN
    floor = float(median(b[2, obj]))
    out = obj.copy()
    for k in parts:
        part = labels == k
        p = b[:, part]
        if p[2].min() > floor and np.all(p[:2].min(axis=1) >= lo) and np.all(p[:2].max(axis=1) <= hi):
            out |= part
    return out
