"""``detect(points, board)``: every object on the board, from one point cloud."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np
from sofia_schemas import Board
from sofia_schemas.messages import DetectedObject, Detection

from .board import fit_board
from .errors import BadCloud
from .geometry.samples import median
from .objects.colour import board_white, lit_share, name_colour, shaded_like_another
from .objects.footprint import ObjectEstimate, estimate_object, half_turn, length_first
from .objects.silhouette import silhouette
from .objects.visibility import InView, in_view
from .params import DetectorParams
from .segment import ObjectPoints, find_objects

DEFAULT_PARAMS = DetectorParams()
HOLES_OK = 0.05  # share of an object's pixels without depth that costs no confidence
TRUNCATED_CONFIDENCE = 0.45  # the centre of a truncated object's visible part is not trusted
# unorganized clouds: the image border and occluders are unseen; on the realistic scenes flattened,
# 90.9 % of their objects are within 5 mm (100 % of organized clouds' objects at >= 0.9)
UNMEASURED_CONFIDENCE = 0.85
OFF_BOARD = 0.5  # an object most of whose surroundings lie below the board stands beside it
Colour = tuple[str | None, tuple[int, int, int] | None]
OUTLINE_CUT = (
    "board outline not fully seen: along a cut axis the board is placed from its one seen edge, "
    "or at its configured position when neither edge is seen"
)


def as_cloud(points: object) -> np.ndarray:
    """Validate a cloud: (N, 3) or organized (H, W, 3) real numbers (NaN and inf mark missing points).

    Raises :class:`BadCloud` naming the received shape or dtype. Arrays are not copied.
    """
    try:
        arr = np.asarray(points)
    except (TypeError, ValueError) as e:
        raise BadCloud(f"cannot be read as an array: {e}") from None
    if arr.dtype.kind not in "fiu":
        raise BadCloud(f"expected real numbers, got dtype {arr.dtype}")
    if arr.ndim not in (2, 3) or arr.shape[-1] != 3:
        raise BadCloud(f"expected shape (N, 3) or (H, W, 3), got {arr.shape}")
    return arr


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


def as_colours(rgb: object, cloud: np.ndarray) -> np.ndarray | None:
    """Validate colours aligned with ``cloud``: uint8 of shape ``cloud.shape`` (or None)."""
    if rgb is None:
        return None
    arr = np.asarray(rgb)
    if arr.shape != cloud.shape:
        raise BadCloud(f"colours of shape {arr.shape} do not match the points {cloud.shape}")
    if arr.dtype != np.uint8:
        if arr.dtype.kind not in "fiu" or not np.all(np.isfinite(arr)):
            raise BadCloud(f"colours must be real numbers 0-255, got dtype {arr.dtype}")
        arr = np.clip(arr, 0, 255).astype(np.uint8)
    return arr


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


def detect(
    points: object,
    board: Board,
    params: DetectorParams = DEFAULT_PARAMS,
    *,
    stamp_ns: int = 0,
    frame_id: str | None = None,
    source: str | None = None,
    rgb: object = None,
) -> Detection:
    """Every object lying on the board.

    points: (N, 3) or organized (H, W, 3) float, the board's frame (``board.frame_id``, usually the
    robot base), metres; NaN or inf mark missing points. board: the configured board; its plane,
    position and yaw are measured from the cloud near it. Returns a :class:`Detection` with the
    objects on red fields first; ``status`` is ``no_object`` for an empty board and ``no_board``
    when the board is not in the cloud. rgb: colours aligned with the points ((N, 3) or (H, W, 3)
    uint8), which name each object's colour and join the pieces of dark objects. Raises
    :class:`BadCloud` for arrays that are not clouds.
    """
    t0 = time.perf_counter()
    cloud = as_cloud(points)
    colours = as_colours(rgb, cloud)
    head: dict[str, Any] = {"stamp_ns": stamp_ns, "frame_id": frame_id or board.frame_id, "source": source}
    organized = cloud.ndim == 3
    n_total = cloud.shape[0] * cloud.shape[1] if organized else cloud.shape[0]
    if n_total == 0:
        return Detection(**head, status="no_board", detail="the cloud has no points")
    # unorganized: every point (subsampling an unorganized cloud can leave stripes: a flattened image)
    fit = fit_board(cloud[:: params.stride, :: params.stride] if organized else cloud, board, params)
    t1 = time.perf_counter()
    timings = {"board_ms": (t1 - t0) * 1e3}
    if fit is None:
        return Detection(
            **head, status="no_board", timings_ms=timings,
            detail=f"no board surface within {params.board_band} m of the configured board "
            f"({n_total} points)",
        )  # fmt: skip
    found = find_objects(cloud, colours, fit, board, params)
    t2 = time.perf_counter()
    white = None
    need_white = colours is not None  # measured once, for the first object named

    def board_white_once() -> np.ndarray | None:
        nonlocal white, need_white
        if need_white and colours is not None:
            s = params.stride
            m, c = (
                (fit.m_coarse, colours[::s, ::s])
                if organized
                else (fit.m_coarse[:, ::7, None], colours[::7, None])
            )
            white = board_white(m, c, fit.T_board_plane, board, params.outline_band)
            need_white = False
        return white

    depth = cloud[..., 2] if organized else None
    objects, placed, slivers = [], [], []
    for obj in found:
        if obj.b.shape[1] < params.min_points:
            continue
        est = estimate_object(obj, fit.plane.rms, params.curvature, params.colour_tol, params.min_width)
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
    t3 = time.perf_counter()
    timings.update(segment_ms=(t2 - t1) * 1e3, objects_ms=(t3 - t2) * 1e3, total_ms=(t3 - t0) * 1e3)
    T = fit.T_base_board
    seen = fit.outline is not None and all(fit.outline.complete)
    return Detection(
        **head,
        status="ok" if objects else "no_object",
        objects=objects,
        board_normal=tuple(float(v) for v in T[:3, 2]),  # type: ignore[arg-type]
        board_offset_m=fit.plane.coef[0],
        board_center=tuple(float(v) for v in T[:3, 3]),  # type: ignore[arg-type]
        board_yaw=float(np.arctan2(T[1, 0], T[0, 0])),
        timings_ms={k: round(v, 3) for k, v in timings.items()},
        detail="" if seen else OUTLINE_CUT,
    )
