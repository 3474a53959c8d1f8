"""The objects stage's entry: each object's estimate, visibility and colour, as messages."""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
from sofia_schemas import Board
from sofia_schemas.messages import DetectedObject

from ..board import BoardFit
from ..geometry.samples import median
from ..params import DetectorParams
from ..segment import ObjectPoints
from .colour import board_white, lit_share, name_colour, shaded_like_another
from .footprint import ObjectEstimate, estimate_object, half_turn, length_first
from .silhouette import silhouette
from .visibility import InView, in_view

HOLES_OK = 0.05  # share of an object's pixels without depth that costs no confidence
TRUNCATED_CONFIDENCE = 0.45  # the centre of a truncated object's visible part is not trusted
# unorganized clouds: the image border and occluders are unseen; on the realistic scenes flattened,
# 90.9 % of their objects are within 5 mm (100 % of organized clouds' objects at >= 0.9)
UNMEASURED_CONFIDENCE = 0.85
OFF_BOARD = 0.5  # an object most of whose surroundings lie below the board stands beside it
Colour = tuple[str | None, tuple[int, int, int] | None]


def measure_objects(
    found: list[ObjectPoints],
    cloud: np.ndarray,
    colours: np.ndarray | None,
    fit: BoardFit,
    board: Board,
    params: DetectorParams,
) -> list[DetectedObject]:
    """The objects of one cloud (H, W, 3) or (N, 3), base frame, metres (colours: uint8 of its shape),
    on red fields first, then by their number of points; those below the height floor, off the
    field grid, beside the board or of mixed pixels dropped, slivers placed by their silhouettes."""
    organized = cloud.ndim == 3

    @cache
    def board_white_once() -> np.ndarray | None:  # measured for the first object named
        if colours is None:
            return None
        s = params.stride
        m, c = (
            (fit.m_coarse, colours[::s, ::s])
            if organized
            else (fit.m_coarse[:, ::7, None], colours[::7, None])
        )
        return board_white(m, c, fit.T_board_plane, board, params.outline_band)

    depth = cloud[..., 2] if organized else None
    objects, placed, slivers = [], [], []
    for obj in found:
        if obj.b.shape[1] < params.min_points:
            continue
        est = estimate_object(obj, fit.plane.rms, params)
        if est.height < params.min_object_height:
            continue  # below the height floor
        if est.whole_size[1] < params.min_width:
            slivers.append((est, obj))  # mixed pixels, or all the depth a dark object returns
            continue
        view = None  # measured only for objects that may be kept
        if est.size[1] < params.min_width:  # a sliver of a top
            view = in_view(obj, est.height, params.colour_tol, depth)
            if not view.reasons:
                continue  # mixed pixels along a silhouette
            # the top out of view (a tall object cut by the image border): what is seen of it
            est = replace(est, center_xy=est.whole_xy, size=est.whole_size)
        if board.field_at(*est.center_xy) is None:
            continue  # not on the field grid
        if view is None:
            view = in_view(obj, est.height, params.colour_tol, depth)
        if view.off_board > OFF_BOARD:
            continue  # beside the board (on the table)
        colour = _colour(obj, est, board_white_once(), params)
        objects.append(_to_message(est, board, fit.T_base_board, fit.plane.rms, view, colour))
        placed.append(est)
    if slivers and colours is not None and organized:
        for est, obj, view in _from_silhouettes(
            slivers, cloud, colours, fit.T_base_board, placed, board, params
        ):
            colour = _colour(obj, est, board_white_once(), params)
            objects.append(_to_message(est, board, fit.T_base_board, fit.plane.rms, view, colour))
    objects.sort(key=lambda o: (not o.allowed, -o.n_points))
    return objects


def _to_message(
    est: ObjectEstimate, board: Board, T_base_board: np.ndarray, noise: float, view: InView, colour: Colour
) -> DetectedObject:
    R, t = T_base_board[:3, :3], T_base_board[:3, 3]
    center = R @ np.array([est.center_xy[0], est.center_xy[1], est.height / 2]) + t
    centroid = R @ est.centroid + t
    axis_base = R[:, :2] @ np.array([np.cos(est.yaw), np.sin(est.yaw)])
    yaw = half_turn(float(np.arctan2(axis_base[1], axis_base[0])))
    fld = board.field_at(*est.center_xy)
    # confidence: enough points for the footprint, a board plane as flat as a depth camera sees it,
    # the whole silhouette in view and depth over the object
    coverage = min(est.n_points / 150.0, 1.0)
    flatness = 1.0 if noise < 0.004 else 0.6
    confidence = coverage * flatness * (1.0 - max(view.holes - HOLES_OK, 0.0))
    if view.reasons:  # truncated: the centre of the visible part
        confidence = min(confidence, TRUNCATED_CONFIDENCE) * view.fraction
    if not view.measured:
        confidence = min(confidence, UNMEASURED_CONFIDENCE)
    return DetectedObject(
        center=tuple(float(v) for v in center),  # type: ignore[arg-type]
        centroid=tuple(float(v) for v in centroid),  # type: ignore[arg-type]
        extents=(est.size[0], est.size[1], est.height),
        yaw=float(yaw), field=fld, allowed=fld is not None and board.is_allowed(*fld),
        n_points=est.n_points, confidence=round(float(np.clip(confidence, 0.0, 1.0)), 3),
        visibility=round(view.fraction, 3), truncated=view.reasons, colour=colour[0], rgb=colour[1],
    )  # fmt: skip


def _colour(
    obj: ObjectPoints, est: ObjectEstimate, white: np.ndarray | None, params: DetectorParams
) -> Colour:
    upper = obj.b[2] >= 0.8 * est.height
    sel = np.flatnonzero(upper) if np.count_nonzero(upper) >= 3 else np.arange(obj.b.shape[1])
    sel = sel[:: max(1, sel.size // 500)]
    if obj.point_rgb is not None:  # an unorganized cloud: the upper points' colours as seen
        return name_colour(median(obj.point_rgb[sel]), white, params.palette)
    if obj.rgb is None or obj.rows is None or obj.cols is None:
        return None, None
    rows, cols = obj.rows[sel], obj.cols[sel]
    named = name_colour(median(obj.rgb[rows, cols]), white, params.palette)
    if obj.window is None or not shaded_like_another(named[0], params.palette):
        return named
    lit = lit_share(obj.window, rows, cols)
    seen = np.isfinite(lit)  # each face's shading undone where its normal is measured
    if np.count_nonzero(seen) < 3:
        return named
    return name_colour(median(obj.rgb[rows[seen], cols[seen]] / lit[seen, None]), white, params.palette)


def _from_silhouettes(
    slivers: list[tuple[ObjectEstimate, ObjectPoints]],
    cloud: np.ndarray,
    rgb: np.ndarray,
    T_base_board: np.ndarray,
    placed: list[ObjectEstimate],
    board: Board,
    params: DetectorParams,
) -> list[tuple[ObjectEstimate, ObjectPoints, InView]]:
    """Objects of which depth saw only slivers, placed from their colour silhouettes
    (:mod:`.silhouette`): the highest sliver first (its height is the top's); a sliver inside a
    silhouette already placed, or a footprint on an object already found, adds nothing."""
    out: list[tuple[ObjectEstimate, ObjectPoints, InView]] = []
    taken = np.zeros(cloud.shape[:2], dtype=bool)
    for est, obj in sorted(slivers, key=lambda s: -s[0].height):
        assert obj.rows is not None and obj.cols is not None
        if taken[obj.rows + obj.origin[0], obj.cols + obj.origin[1]].any():
            continue
        sil = silhouette(obj, cloud, rgb, T_base_board, est.height, params.colour_tol)
        if sil is None:
            continue
        taken[sil.rows, sil.cols] = True  # the other slivers of this object
        rect = sil.rect
        if rect is None or board.field_at(*rect.center) is None or any(p.covers(rect.center) for p in placed):
            continue  # not placed, off the field grid, or on an object already found
        size, yaw = length_first(rect.size, rect.yaw)
        est = replace(est, center_xy=rect.center, size=size, whole_xy=rect.center, whole_size=size, yaw=yaw)
        out.append((est, obj, InView(1.0, ("depth_holes",), sil.missing, sil.missing)))
    return out
