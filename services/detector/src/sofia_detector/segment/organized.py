"""Objects of an organized cloud: seeds on the coarse pixel grid (heights above the measured
plane), then full resolution only inside each seed's pixel window."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from scipy import ndimage

from ..board import BoardFit
from ..depth import raised_pixels
from ..depth.clean import pixel_spacing
from ..geometry.grid import where
from ..geometry.points import points_in_frame
from ..geometry.samples import median
from ..params import DetectorParams
from .points import ObjectPoints

MIN_PART = 10  # pixels of the smallest part standing on an object that is joined to it
PART_MARGIN = 0.005  # metres


def organized_objects(
    points_base: np.ndarray,
    fit: BoardFit,
    half: np.ndarray,
    params: DetectorParams,
    point: float,
    noise: float,
    rgb: np.ndarray | None = None,
) -> Iterator[ObjectPoints]:
    """Objects of points_base (H, W, 3) float, base frame, metres; fit.m_coarse: (3, h, w) float32,
    ``points_base[::stride, ::stride]`` in the plane frame. half: (2,) half size of the region of
    object centres, board frame. point: height (metres) of an object's full-resolution point, noise:
    the board's depth noise (metres). rgb: (H, W, 3) uint8 or None."""
    s, m_coarse, T_board_plane = params.stride, fit.m_coarse, fit.T_board_plane
    H, W = points_base.shape[:2]
    spacing = pixel_spacing(m_coarse, s)  # metres between full-resolution pixels
    seed = max(params.seed_height, params.noise_k * noise)  # height of a coarse object pixel
    delta = params.neighbour_px * spacing + 3 * noise  # consistent_at's distance at full resolution
    rgb_coarse = None if rgb is None else rgb[::s, ::s]
    raised = raised_pixels(
        m_coarse, seed, params.max_height, 2 * s * spacing + 4 * noise, rgb_coarse, params.colour_tol
    )
    seeds, labels, n = raised.mask, raised.labels, raised.n
    claimed = np.zeros((H, W), dtype=bool)  # the pixels of the objects found so far
    for i, sl in enumerate(ndimage.find_objects(labels, max_label=n), start=1):
        comp = (labels[sl] == i) & seeds[sl]
        sr, sc = where(comp)
        if sr.size < params.min_seed_pixels:
            continue
        xy_plane = m_coarse[:2][:, sl[0], sl[1]][:, comp].mean(axis=1)
        if not np.all(np.abs(T_board_plane[:2, :2] @ xy_plane + T_board_plane[:2, 3]) < half):
            continue  # clutter beside the board
        rows, cols = (sr + sl[0].start) * s, (sc + sl[1].start) * s  # full-resolution seed pixels
        if claimed[rows, cols].any():
            continue  # a second seed of an object already found (holes in the cloud split it)
        r0, r1 = max((sl[0].start - 2) * s, 0), min((sl[0].stop + 2) * s, H)  # 2 coarse pixels around
        c0, c1 = max((sl[1].start - 2) * s, 0), min((sl[1].stop + 2) * s, W)
        b = points_in_frame(points_base[r0:r1, c0:c1], fit.T_base_board)
        window = raised_pixels(b, point, params.max_height, delta)
        wl, n_pieces = window.labels, window.n
        counts = np.bincount(wl[rows - r0, cols - c0], minlength=1)  # seed hits per piece
        counts[0] = 0
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
    sizes[pieces] = sizes[0] = 0
    parts = np.flatnonzero(sizes >= MIN_PART)
    if parts.size == 0:
        return obj
    xy = b[:2, obj]
    lo, hi = xy.min(axis=1) - PART_MARGIN, xy.max(axis=1) + PART_MARGIN
    low = np.array([ndimage.minimum(c, labels, parts) for c in b])  # (3, k) of each part
    high = np.array([ndimage.maximum(c, labels, parts) for c in b[:2]])
    on = (low[2] > median(b[2, obj])) & np.all((low[:2] >= lo[:, None]) & (high <= hi[:, None]), axis=0)
    return obj | np.isin(labels, parts[on])  # type: ignore[no-any-return]
