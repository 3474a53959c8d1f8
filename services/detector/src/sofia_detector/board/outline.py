"""Rectangles around 2-D point sets, and where the board lies in its plane.

The board top's outline gives the yaw (least-area rectangle) and the centre: the midpoint of
opposite edges where both drop to the table; half the fields and a rim inside the one edge seen
where the other is cut short (missing depth, the image border, the fingers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.rect import min_area_rect


@dataclass(frozen=True)
class Outline:
    """Board rectangle in the plane frame (metres, radians); ``complete`` per board axis."""

    center: tuple[float, float]
    yaw: float
    size: tuple[float, float]
    complete: tuple[bool, bool]


def _side_counts(
    xy: np.ndarray, drop_xy: np.ndarray | None, R: np.ndarray, side_band: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per side of a rectangle (x lo, y lo, x hi, y hi; axes the columns of ``R`` (2, 2)): how many
    of the points ``xy`` (k, 2) lie within ``side_band`` of the outermost one, and how many of those
    drop outwards (``drop_xy`` (k, 2) within 60 degrees of the side's normal; None: all do)."""
    uv = xy @ R
    u = np.concatenate([-uv, uv], axis=1).T  # (4, k) outwards of each side
    near = u >= u.max(axis=1, keepdims=True) - side_band
    if drop_xy is None:
        out = near
    else:
        d = drop_xy @ R
        d = np.concatenate([-d, d], axis=1).T
        out = near & (d > 0.5 * np.hypot(drop_xy[:, 0], drop_xy[:, 1]))
    return near.sum(axis=1), out.sum(axis=1)


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
