"""Rectangles around 2-D point sets, and where the board lies in its plane.

The board top is the largest connected patch of points at height ~0. Its outline gives the board
yaw (the rectangle of least area: one of its sides lies along an edge of the convex hull) and its
centre: the midpoint of opposite edges (whatever the width of the rim around the fields) where
both are the board's edges, a drop to the table beside them; half the fields and a rim inside the
one edge seen where the other side is cut short (missing depth, the image border, the fingers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from .kernels import jit
from .pixels import where

QUARTER = math.pi / 2


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

    @cached_property
    def R(self) -> np.ndarray:
        """(2, 2) rotation whose columns are the rectangle axes (computed once per rectangle: the
        detector reads it, the centre and the size many times)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return _read_only(np.array([[c, -s], [s, c]]))

    @cached_property
    def center(self) -> np.ndarray:
        """(2,) centre in the frame of the points."""
        return _read_only(self.R @ ((self.lo + self.hi) / 2))

    @cached_property
    def size(self) -> np.ndarray:
        """(2,) extent along the rectangle's two axes."""
        return _read_only(self.hi - self.lo)


def _read_only(a: np.ndarray) -> np.ndarray:
    """``a``, marked read-only: a rectangle's cached values are shared by whoever reads them."""
    a.flags.writeable = False
    return a


def grid_boundary(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row/column extremes of a 2-D mask: every vertex of its convex hull is among them.

    Returns (rows (k,), cols (k,)) int indices of the first and last True cell of every non-empty
    row, then of every non-empty column.
    """
    rows, cols = where(mask)
    at = boundary_points(rows, cols, *mask.shape)
    return rows[at], cols[at]


@jit
def boundary_points(
    rows: np.ndarray, cols: np.ndarray, h: int, w: int, subset: np.ndarray | None = None
) -> np.ndarray:
    """:func:`grid_boundary` of pixels given by index: (k,) indices into rows, cols (n,) (distinct
    pixels of an (h, w) grid) of the first and last pixel of every non-empty row, then of every
    non-empty column, in :func:`grid_boundary`'s order. subset: (n,) bool, only those pixels
    (the indices still into rows, cols: nothing is gathered)."""
    first_c, last_c = np.full(h, -1), np.full(h, -1)  # the point at the row's first, last column
    first_r, last_r = np.full(w, -1), np.full(w, -1)
    for i in range(rows.size):
        if subset is not None and not subset[i]:
            continue
        r, c = rows[i], cols[i]
        if first_c[r] < 0 or c < cols[first_c[r]]:
            first_c[r] = i
        if last_c[r] < 0 or c > cols[last_c[r]]:
            last_c[r] = i
        if first_r[c] < 0 or r < rows[first_r[c]]:
            first_r[c] = i
        if last_r[c] < 0 or r > rows[last_r[c]]:
            last_r[c] = i
    by_row, by_col = first_c[first_c >= 0], first_r[first_r >= 0]
    return np.concatenate((by_row, last_c[last_c >= 0], by_col, last_r[last_r >= 0]))


def hull(xy: np.ndarray) -> np.ndarray:
    """(k, 2) float64 convex hull vertices of ``xy`` (n, 2) (OpenCV's; the points themselves when
    fewer than 3)."""
    xy = np.asarray(xy, dtype=np.float64)
    if xy.shape[0] < 3:
        return xy
    at = cv2.convexHull((xy - xy[0]).astype(np.float32), returnPoints=False)
    return xy[at[:, 0]]


def min_area_rect(xy: np.ndarray, max_yaw: float | None = None) -> Rect:
    """Minimum-area rectangle of 2-D points: one of its sides lies along an edge of their convex hull.

    xy: (k, 2) float, metres, k >= 1. max_yaw: if given, only yaws in ``[-max_yaw, max_yaw]`` are
    considered (0 when no hull edge is in range). OpenCV's ``minAreaRect``, or when its yaw is not
    allowed, the least over the allowed edges of the hull. The returned yaw is in ``[-pi/4, pi/4)``.
    """
    xy = np.asarray(xy, dtype=np.float64)
    (cx, cy), size, angle = cv2.minAreaRect((xy - xy[0]).astype(np.float32))  # float32: 0.1 um here
    turned = math.radians(angle)
    yaw = (turned + QUARTER / 2) % QUARTER - QUARTER / 2
    if max_yaw is None or abs(yaw) <= max_yaw:  # the least of all is the least of those allowed
        if round((turned - yaw) / QUARTER) % 2:
            size = size[::-1]
        c, s = math.cos(yaw), math.sin(yaw)
        x0, y0 = cx + xy[0, 0], cy + xy[0, 1]
        mid = np.array([c * x0 + s * y0, -s * x0 + c * y0])
        return Rect(yaw, mid - np.array(size) / 2, mid + np.array(size) / 2)
    v = hull(xy)
    edge = np.roll(v, -1, axis=0) - v
    yaws = (np.arctan2(edge[:, 1], edge[:, 0]) + QUARTER / 2) % QUARTER - QUARTER / 2
    yaws = yaws[np.abs(yaws) <= max_yaw]
    if yaws.size == 0:
        yaws = np.zeros(1)
    c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
    u, w = c * v[:, 0] + s * v[:, 1], c * v[:, 1] - s * v[:, 0]  # (yaws, k) along the two axes
    lo, hi = np.stack([u.min(axis=1), w.min(axis=1)], 1), np.stack([u.max(axis=1), w.max(axis=1)], 1)
    i = int(np.argmin(np.prod(hi - lo, axis=1)))
    return Rect(float(yaws[i]), lo[i], hi[i])


@jit
def _side_counts(
    xy: np.ndarray, drop_xy: np.ndarray | None, R: np.ndarray, side_band: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per side of a rectangle (x lo, y lo, x hi, y hi; axes the columns of ``R`` (2, 2)): how many
    of the points ``xy`` (k, 2) lie within ``side_band`` of the outermost one, and how many of those
    drop outwards (``drop_xy`` (k, 2) within 60 degrees of the side's normal; None: all do)."""
    k = xy.shape[0]
    u = np.empty((4, k))  # outwards of each side
    for i in range(k):
        u[2, i] = R[0, 0] * xy[i, 0] + R[1, 0] * xy[i, 1]
        u[3, i] = R[0, 1] * xy[i, 0] + R[1, 1] * xy[i, 1]
        u[0, i], u[1, i] = -u[2, i], -u[3, i]
    n_near, n_out = np.zeros(4, dtype=np.int64), np.zeros(4, dtype=np.int64)
    for s in range(4):
        edge = u[s].max() - side_band
        for i in range(k):
            if u[s, i] >= edge:
                n_near[s] += 1
                if drop_xy is None:
                    n_out[s] += 1
                    continue
                dx, dy = drop_xy[i, 0], drop_xy[i, 1]
                d = R[0, s % 2] * dx + R[1, s % 2] * dy
                n_out[s] += (d if s >= 2 else -d) > 0.5 * np.hypot(dx, dy)
    return n_near, n_out


def fit_outline(
    boundary_xy: np.ndarray,
    field_extent: tuple[float, float],
    max_yaw: float,
    max_rim: float,
    drop_xy: np.ndarray | None = None,
    side_band: float = 0.015,
    edge_share: float = 0.3,
) -> Outline:
    """The board rectangle from its outline points.

    boundary_xy: (k, 2) float, plane frame, metres: points on (or including) the outline.
    field_extent: size of the field grid along the board x and y, metres. drop_xy: (k, 2)
    direction (any length) from each point to what lies below the board beside it, 0 where nothing
    does (the board top cut short by missing depth, the image border or something in front of it);
    None: the whole outline is the board's edge. A side of the rectangle is an edge of the board
    when at least ``edge_share`` of the points within ``side_band`` metres of it drop outwards
    (within 60 degrees); the rest may be hidden by the fingers or objects standing on the edge.

    Per axis: with both sides edges and a size within ``[extent - 1 cm, extent + 2 max_rim]``, the
    centre is their midpoint (the axis is complete). With one side an edge, the board ends there:
    the centre lies half the fields and a rim inside it, the rim measured on the other axis when
    that one is complete, else ``max_rim / 2``. With neither, the midpoint when the size is
    within the range above, else the configured 0. A size beyond ``extent + 2 max_rim`` (the board
    top merged with something at board height) keeps the configured 0 as well.
    """
    rect = min_area_rect(boundary_xy, max_yaw)
    R = rect.R
    xy = np.ascontiguousarray(boundary_xy, dtype=np.float64)
    drops = None if drop_xy is None else np.ascontiguousarray(drop_xy, dtype=np.float64)
    n_near, n_out = _side_counts(xy, drops, R, side_band)
    edge = (n_out >= edge_share * np.maximum(n_near, 1)).tolist()
    lo, hi, ext = rect.lo.tolist(), rect.hi.tolist(), field_extent
    size = [hi[a] - lo[a] for a in (0, 1)]
    fits = [size[a] <= ext[a] + 2 * max_rim for a in (0, 1)]
    plausible = [fits[a] and size[a] >= ext[a] - 0.01 for a in (0, 1)]
    ok = [plausible[a] and edge[a] and edge[a + 2] for a in (0, 1)]
    mid = [0.0, 0.0]
    for a in (0, 1):
        if plausible[a] and edge[a] == edge[a + 2]:  # both sides edges, or neither
            mid[a] = (lo[a] + hi[a]) / 2
        elif fits[a] and edge[a] != edge[a + 2]:  # one side cut short: the board ends at the other
            b = 1 - a
            rim = min(max((size[b] - ext[b]) / 2, 0.0), max_rim) if ok[b] else max_rim / 2
            mid[a] = hi[a] - ext[a] / 2 - rim if edge[a + 2] else lo[a] + ext[a] / 2 + rim
    center = R @ mid
    return Outline(
        (float(center[0]), float(center[1])), rect.yaw, (float(size[0]), float(size[1])),
        (bool(ok[0]), bool(ok[1])),
    )  # fmt: skip
