"""Rectangles around 2-D point sets, and where the board lies in its plane.

The board top is the largest connected patch of points at height ~0. Its outline gives the board
centre (midpoint of opposite edges, whatever the width of the rim around the fields) and its yaw
(the rectangle of least area: one of its sides lies along an edge of the convex hull).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from .kernels import hull_indices, least_area_box


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
    """(k, 2) float64 convex hull vertices, counter-clockwise (the points themselves when they span
    no area)."""
    xy = np.ascontiguousarray(xy, dtype=np.float64)
    if not xy.flags.writeable:  # the kernels are compiled for writeable arrays
        xy = xy.copy()
    if xy.shape[0] < 3:
        return xy
    idx = hull_indices(xy)
    return xy[idx] if idx.size >= 3 else xy


def min_area_rect(xy: np.ndarray, max_yaw: float | None = None) -> Rect:
    """Minimum-area rectangle of 2-D points (rotating calipers over the hull edges).

    xy: (k, 2) float, metres, k >= 1. max_yaw: if given, only yaws in ``[-max_yaw, max_yaw]`` are
    considered (0 when no hull edge is in range). The returned yaw is in ``[-pi/4, pi/4)``.
    """
    yaw, lo, hi = least_area_box(hull(xy), np.inf if max_yaw is None else float(max_yaw))
    return Rect(float(yaw), lo, hi)


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
