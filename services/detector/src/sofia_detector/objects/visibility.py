"""How much of an object is in view: where its silhouette runs along the image border, something
nearer or missing depth of its colour, it goes on out of view; elsewhere the board borders it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..depth.clean import median_chroma, of_colour
from ..geometry.grid import grow, shrink
from ..segment.points import ObjectPoints

OCCLUDER_ABOVE = 0.015  # a neighbour this much above the object's top is in front of it, metres
TRUNCATED = 0.04  # share of the silhouette out of view above which an object is truncated
BELOW_BOARD = 0.01  # neighbours this far below the board surface: the object stands off the board


@dataclass(frozen=True)
class InView:
    """Share in view (0-1); what hides the rest (``image_edge``, ``occluded``, ``depth_holes``);
    lost: share of the silhouette out of view; holes: share of its pixels without depth;
    off_board: share of its surroundings at or below board level lying below it; measured: False
    for an unorganized cloud (no pixel grid to tell)."""

    fraction: float
    reasons: tuple[str, ...]
    lost: float
    holes: float
    off_board: float = 0.0
    measured: bool = True


def in_view(obj: ObjectPoints, top: float, tol: float, depth: np.ndarray | None = None) -> InView:
    """Visibility of an object whose top is ``top`` metres above the board. depth: (H, W) the
    cloud's z (NaN where missing): an object reaching a row's first column with depth meets an
    image edge there (the band the second imager does not see, as wide as the disparity)."""
    if obj.rows is None or obj.cols is None or obj.window is None:
        return InView(1.0, (), 0.0, 0.0, 0.0, measured=False)
    (r0, c0), (H, W) = obj.origin, obj.image_shape
    lo_r, hi_r, lo_c, hi_c = (
        int(v) for v in (obj.rows.min(), obj.rows.max(), obj.cols.min(), obj.cols.max())
    )
    edge = 0
    first = np.full(hi_r - lo_r + 1, -2)  # per row of the object: its first column with depth
    if depth is not None and lo_c + c0 < W // 3:  # the band is narrower than a third of the image
        stop = min(hi_c + c0 + 1, W // 3)
        seen = np.isfinite(depth[lo_r + r0 : hi_r + r0 + 1, :stop])
        first = np.where(seen.any(axis=1), np.argmax(seen, axis=1), stop)
    if lo_r + r0 == 0 or hi_r + r0 == H - 1 or lo_c + c0 <= first.max() + 1 or hi_c + c0 == W - 1:
        rows, cols = obj.rows + r0, obj.cols + c0
        left = cols <= first[obj.rows - lo_r] + 1
        border = (rows == 0) | (rows == H - 1) | left | (cols == W - 1)
        edge = 2 * int(np.count_nonzero(border))
    crop = (
        slice(max(lo_r - 4, 0), min(hi_r + 5, obj.shape[0])),
        slice(max(lo_c - 4, 0), min(hi_c + 5, obj.shape[1])),
    )
    mask = np.zeros((crop[0].stop - crop[0].start, crop[1].stop - crop[1].start), dtype=bool)
    mask[obj.rows - crop[0].start, obj.cols - crop[1].start] = True
    h = obj.window[2][crop]
    ring = grow(mask, 5) & ~mask  # within 2 pixels of the object
    near = grow(mask, 7) & np.isnan(h)  # missing depth within 3 pixels
    z = h[ring]
    with np.errstate(invalid="ignore"):  # in front of the object, beside the board, at board level
        occluded, low, level = (
            int(np.count_nonzero(k))
            for k in (z > top + OCCLUDER_ABOVE, z < -BELOW_BOARD, abs(z) <= BELOW_BOARD)
        )
    holes, inner_holes = 0, 0.0
    if obj.rgb is not None and near.any():  # missing depth of the object's colour: its holes
        same = np.zeros(mask.shape, dtype=bool)
        same[near] = of_colour(obj.rgb[crop][near], median_chroma(obj.rgb, obj.rows[::4], obj.cols[::4]), tol)
        shadow = np.zeros_like(mask)  # the object's own stereo shadow: two pixels on its left
        shadow[:, :-1] = mask[:, 1:]
        shadow[:, :-2] |= mask[:, 2:]
        holes = int(np.count_nonzero(ring & grow(shrink(same, 3), 3) & ~shadow))  # by 3 x 3 blocks of holes
        n_same = int(np.count_nonzero(same))
        inner_holes = n_same / (n_same + obj.rows.size)
    n = int(z.size) + edge
    lost = (edge + occluded + holes) / max(n, 1)
    hidden = (("image_edge", edge), ("occluded", occluded), ("depth_holes", holes))
    reasons = tuple(name for name, k in hidden if k > 0.02 * n) if lost > TRUNCATED else ()
    return InView(min(max(1.0 - 1.2 * lost, 0.0), 1.0), reasons, lost, inner_holes, low / max(low + level, 1))
