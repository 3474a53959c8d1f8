"""Where the board lies in its plane: the yaw of the least-area rectangle around its top's outline,
the centre between opposite edges, or half the fields and a rim inside the one edge seen."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.rect import min_area_rect

SIDE_BAND = 0.015  # metres from a side within which outline points belong to it
EDGE_SHARE = 0.3  # share of a side's points dropping outwards above which it is the board's edge


@dataclass(frozen=True)
class Outline:
    """Board rectangle in the plane frame (metres, radians); ``complete`` per board axis."""

    center: tuple[float, float]
    yaw: float
    size: tuple[float, float]
    complete: tuple[bool, bool]


def fit_outline(
    boundary_xy: np.ndarray,
    field_extent: tuple[float, float],
    max_yaw: float,
    max_rim: float,
    drop_xy: np.ndarray | None = None,
) -> Outline:
    """The board rectangle from boundary_xy (k, 2), points including its outline (plane frame,
    metres). field_extent: the field grid's size along board x and y. drop_xy: (k, 2) direction
    from each point to what lies below the board beside it, 0 where nothing does; None: all the
    outline is the board's edge. A side is an edge when :data:`EDGE_SHARE` of the points within
    :data:`SIDE_BAND` of it drop outwards (within 60 degrees).

    Per axis: both sides edges and a size within ``[extent - 1 cm, extent + 2 max_rim]``: their
    midpoint (complete). One side an edge: half the fields and a rim inside it (the rim measured on
    the other axis when complete, else ``max_rim / 2``). Neither: the midpoint when the size is in
    that range, else the configured 0, as for a size beyond it (the top merged with something).
    """
    rect = min_area_rect(boundary_xy, max_yaw)
    R = rect.R
    out_uv = np.concatenate([-boundary_xy @ R, boundary_xy @ R], axis=1).T  # (4, k): x lo, y lo, x hi, y hi
    near = out_uv >= out_uv.max(axis=1, keepdims=True) - SIDE_BAND
    out = near
    if drop_xy is not None:  # those dropping outwards, within 60 degrees of the side's normal
        d = np.concatenate([-drop_xy @ R, drop_xy @ R], axis=1).T
        out = near & (d > 0.5 * np.hypot(drop_xy[:, 0], drop_xy[:, 1]))
    n_near, n_out = np.count_nonzero(near, axis=1), np.count_nonzero(out, axis=1)
    edge = (n_out >= EDGE_SHARE * np.maximum(n_near, 1)).tolist()
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
