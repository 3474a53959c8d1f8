"""How much of an object is in view: where its silhouette runs along the image border, something
nearer (the fingers) or missing depth of its own colour, the object goes on out of view and the
centre of its visible part is biased; elsewhere the board (or its stereo shadow) borders it.
"""

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
    """fraction: estimated share of the object in view (0-1). reasons: what hides the rest
    (``image_edge``, ``occluded``, ``depth_holes``). lost: share of the silhouette out of view.
    holes: share of the object's pixels without depth. off_board: share of its surroundings
    (among those at or below board level) lying below the board: it stands beside the board.
    measured: False for an unorganized cloud, whose missing pixel grid cannot tell any of this."""

    fraction: float
    reasons: tuple[str, ...]
    lost: float
    holes: float
    off_board: float = 0.0
    measured: bool = True


def seen_from(depth: np.ndarray, rows: slice, stop: int) -> np.ndarray:
    """The first column with depth in each of ``rows`` of ``depth`` (H, W) (z of an organized cloud,
    NaN where missing), searched in its first ``stop`` columns (``stop`` when none has depth).
    The band on the image's left that the second imager does not see is as wide as the disparity:
    wider for nearer surfaces, so an object's top ends it further right than the board does."""
    seen = np.isfinite(depth[rows, :stop])
    return np.where(seen.any(axis=1), np.argmax(seen, axis=1), stop)


def _ring(
    mask: np.ndarray, h: np.ndarray, above: float, below: float
) -> tuple[np.ndarray, int, int, int, int, np.ndarray]:
    """The ring around an object's pixels ``mask`` (h, w) bool: the pixels within 2 of it, not on
    it, (h, w) bool; how many; how many of them are higher than ``above`` (in front of the object),
    lower than ``-below`` (beside the board) and within ``below`` of the board (heights ``h``
    (h, w) float32, NaN where missing, metres); and the pixels without depth within 3 of it."""
    ring = grow(mask, 5) & ~mask
    near = grow(mask, 7) & np.isnan(h)
    z = h[ring]
    with np.errstate(invalid="ignore"):
        occluded, low, level = (int(np.count_nonzero(k)) for k in (z > above, z < -below, abs(z) <= below))
    return ring, int(z.size), occluded, low, level, near


def _holes(
    mask: np.ndarray, ring: np.ndarray, near: np.ndarray, rgb: np.ndarray, own: np.ndarray, tol: float
) -> tuple[int, int]:
    """(ring pixels beside missing depth of the object's colour, pixels of that missing depth):
    ``near`` (h, w) bool pixels of the object's colour (``own`` (4,) :func:`.depth_clean.chroma`
    within ``tol``, colours ``rgb`` (h, w, 3) uint8) are its holes; of the ``ring`` pixels those
    within a pixel of a 3 x 3 block of holes (not the grazing slivers along rims) count, except
    the object's own stereo shadow (the two pixels left of ``mask``)."""
    same = np.zeros(mask.shape, dtype=bool)
    same[near] = of_colour(rgb[near], own, tol)
    shadow = np.zeros_like(mask)
    shadow[:, :-1] = mask[:, 1:]
    shadow[:, :-2] |= mask[:, 2:]
    holes = ring & grow(shrink(same, 3), 3) & ~shadow
    return int(np.count_nonzero(holes)), int(np.count_nonzero(same))


def in_view(obj: ObjectPoints, top: float, tol: float, depth: np.ndarray | None = None) -> InView:
    """Visibility of an object of an organized cloud whose top is ``top`` metres above the board.

    depth: (H, W) the cloud's z (NaN where missing). Where the object reaches the first column with
    depth of a row (:func:`seen_from`), everything to its left up to the image border is unseen:
    an image edge. Missing depth just left of the object is its own stereo shadow (the second
    imager sits to the right), not a hole in it.
    """
    if obj.rows is None or obj.cols is None or obj.window is None:
        return InView(1.0, (), 0.0, 0.0, 0.0, measured=False)
    (r0, c0), (H, W) = obj.origin, obj.image_shape
    lo_r, hi_r, lo_c, hi_c = (
        int(v) for v in (obj.rows.min(), obj.rows.max(), obj.cols.min(), obj.cols.max())
    )
    edge = 0
    first = np.full(hi_r - lo_r + 1, -2)  # per row of the object: its first column with depth
    if depth is not None and lo_c + c0 < W // 3:  # the band is narrower than a third of the image
        first = seen_from(depth, slice(lo_r + r0, hi_r + r0 + 1), min(hi_c + c0 + 1, W // 3))
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
    ring, n_ring, occluded, low, level, near = _ring(
        mask, obj.window[2][crop], top + OCCLUDER_ABOVE, BELOW_BOARD
    )
    holes, inner_holes = 0, 0.0
    if obj.rgb is not None and near.any():
        own = median_chroma(obj.rgb, obj.rows[::4], obj.cols[::4])
        holes, n_same = _holes(mask, ring, near, obj.rgb[crop], own, tol)
        inner_holes = n_same / (n_same + obj.rows.size)
    n = n_ring + edge
    lost = (edge + occluded + holes) / max(n, 1)
    reasons = tuple(
        name
        for name, k in (("image_edge", edge), ("occluded", occluded), ("depth_holes", holes))
        if k > 0.02 * n
    )
    return InView(
        min(max(1.0 - 1.2 * lost, 0.0), 1.0),
        reasons if lost > TRUNCATED else (),
        lost,
        inner_holes,
        low / max(low + level, 1),
    )
