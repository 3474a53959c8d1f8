"""``detect(points, board)``: every object on the board, from one point cloud."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from sofia_schemas import Board
from sofia_schemas.messages import Detection

from .board import fit_board
from .errors import BadCloud
from .objects import measure_objects
from .params import DetectorParams
from .segment import find_objects

DEFAULT_PARAMS = DetectorParams()
OUTLINE_CUT = (
    "board outline not fully seen: along a cut axis the board is placed from its one seen edge, "
    "or at its configured position when neither edge is seen"
)


def as_cloud(points: object) -> np.ndarray:
    """The cloud, not copied: (N, 3) or (H, W, 3) real numbers (NaN, inf: missing), else
    :class:`BadCloud` naming the shape or dtype received."""
    try:
        arr = np.asarray(points)
    except (TypeError, ValueError) as e:
        raise BadCloud(f"cannot be read as an array: {e}") from None
    if arr.dtype.kind not in "fiu":
        raise BadCloud(f"expected real numbers, got dtype {arr.dtype}")
    if arr.ndim not in (2, 3) or arr.shape[-1] != 3:
        raise BadCloud(f"expected shape (N, 3) or (H, W, 3), got {arr.shape}")
    return arr


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
    """Every object lying on the board, objects on red fields first.

    points: (N, 3) or (H, W, 3) float, ``board.frame_id`` (the robot base), metres; NaN or inf
    missing. board: its plane, position and yaw are measured near the configured one. rgb: uint8
    colours of the points' shape. ``status``: ``no_object`` for an empty board, ``no_board`` when
    it is not in the cloud. Raises :class:`BadCloud` for arrays that are not clouds.
    """
    t0 = time.perf_counter()
    cloud = as_cloud(points)
    colours = as_colours(rgb, cloud)
    head: dict[str, Any] = {"stamp_ns": stamp_ns, "frame_id": frame_id or board.frame_id, "source": source}
    n_total = cloud.size // 3
    if n_total == 0:
        return Detection(**head, status="no_board", detail="the cloud has no points")
    # unorganized: every point (subsampling an unorganized cloud can leave stripes: a flattened image)
    fit = fit_board(cloud[:: params.stride, :: params.stride] if cloud.ndim == 3 else cloud, board, params)
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
    objects = measure_objects(found, cloud, colours, fit, board, params)
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
