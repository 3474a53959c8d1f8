"""Rectangles around 2-D point sets, and where the board lies in its plane.

The board top is the largest connected patch of points at height ~0. Its outline gives the board
centre (midpoint of opposite edges, whatever the width of the rim around the fields) and its yaw
(the rectangle of least area: one of its sides lies along an edge of the convex hull).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull, QhullError

QUARTER = np.pi / 2


@dataclass(frozen=True)
class Outline:
    """Board rectangle in the plane frame (metres, radians); ``complete`` per board axis."""

    center: tuple[float, float]
    yaw: float
    size: tuple[float, float]
    complete: tuple[bool, bool]


@dataclass(frozen=True)
class Rect:
    """Rectangle: ``yaw`` of its first axis; ``lo``, ``hi`` (2,) bounds along its two axes."""

    yaw: float
    lo: np.ndarray
    hi: np.ndarray

    @property
    def R(self) -> np.ndarray:
        """(2, 2) rotation whose columns are the rectangle axes."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return np.array([[c, -s], [s, c]])

    @property
    def center(self) -> np.ndarray:
        """(2,) centre in the frame of the points."""
        return self.R @ ((self.lo + self.hi) / 2)

    @property
    def size(self) -> np.ndarray:
        return self.hi - self.lo


def largest_component(mask: np.ndarray) -> np.ndarray:
    """The largest 8-connected component of a 2-D boolean mask (empty mask in, empty mask out)."""
    labels, n = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
    if n == 0:
        return mask
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return labels == int(np.argmax(sizes))


def grid_boundary(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row/column extremes of a 2-D mask: every vertex of its convex hull is among them.

    Returns (rows (k,), cols (k,)) int indices of the first and last True cell of every non-empty
    row and column.
    """
    h, w = mask.shape
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    first_c = np.argmax(mask, axis=1)[rows]
    last_c = w - 1 - np.argmax(mask[:, ::-1], axis=1)[rows]
    first_r = np.argmax(mask, axis=0)[cols]
    last_r = h - 1 - np.argmax(mask[::-1], axis=0)[cols]
    return np.concatenate([rows, rows, first_r, last_r]), np.concatenate([first_c, last_c, cols, cols])


def hull(xy: np.ndarray) -> np.ndarray:
    """(k, 2) float64 convex hull vertices in order (the points themselves when degenerate)."""
    xy = np.asarray(xy, dtype=np.float64)
    if xy.shape[0] < 3:
        return xy
    try:
        return xy[ConvexHull(xy).vertices]
    except QhullError:
        return xy


def rect_extents(xy: np.ndarray, yaws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of 2-D points along rotated axes.

    xy: (k, 2) float, metres. yaws: (m,) radians. Returns lo (m, 2) and hi (m, 2): min and max of
    the projections on ``(cos, sin)`` and ``(-sin, cos)`` of each yaw.
    """
    c, s = np.cos(yaws), np.sin(yaws)
    x, y = xy[None, :, 0], xy[None, :, 1]
    u = c[:, None] * x + s[:, None] * y
    v = -s[:, None] * x + c[:, None] * y
    lo = np.stack([u.min(axis=1), v.min(axis=1)], axis=1)
    hi = np.stack([u.max(axis=1), v.max(axis=1)], axis=1)
    return lo, hi


def min_area_rect(xy: np.ndarray, max_yaw: float | None = None) -> Rect:
    """Minimum-area rectangle of 2-D points (rotating calipers over the hull edges).

    xy: (k, 2) float, metres, k >= 1. max_yaw: if given, only yaws in ``[-max_yaw, max_yaw]`` are
    considered (0 when no hull edge is in range). The returned yaw is in ``[-pi/4, pi/4)``.
    """
    v = hull(xy)
    edges = np.concatenate([v[1:], v[:1]]) - v  # vertex i+1 - vertex i, cyclic
    yaws = (np.arctan2(edges[:, 1], edges[:, 0]) + np.pi / 4) % QUARTER - np.pi / 4
    if max_yaw is not None:
        yaws = yaws[np.abs(yaws) <= max_yaw]
    if yaws.size == 0:
        yaws = np.zeros(1)
    lo, hi = rect_extents(v, yaws)
    i = int(np.argmin(np.prod(hi - lo, axis=1)))
    return Rect(float(yaws[i]), lo[i], hi[i])


def fit_outline(
    boundary_xy: np.ndarray, field_extent: tuple[float, float], max_yaw: float, max_rim: float
) -> Outline:
    """The board rectangle from its outline points.

    boundary_xy: (k, 2) float, plane frame, metres: points on (or including) the outline.
    field_extent: size of the field grid along the board x and y, metres. An axis whose measured
    size is not within ``[extent - 1 cm, extent + 2 max_rim]`` (board partly out of view, or merged
    with something at board height) is not trusted: its centre stays at the configured 0.
    """
    rect = min_area_rect(boundary_xy, max_yaw)
    size = rect.size
    ext = np.asarray(field_extent)
    ok = (size >= ext - 0.01) & (size <= ext + 2 * max_rim)
    mid = np.where(ok, (rect.lo + rect.hi) / 2, 0.0)
    center = rect.R @ mid
    return Outline(
        (float(center[0]), float(center[1])), rect.yaw, (float(size[0]), float(size[1])),
        (bool(ok[0]), bool(ok[1])),
    )  # fmt: skip
