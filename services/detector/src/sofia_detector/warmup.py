"""Warm the detector service before its first cloud: lazy imports (``rosbags``), first calls. Without
it the first detection took 60-110 ms (mostly waiting for the GIL) and, at 30 Hz with a backlog of one,
the next cloud was dropped. The scene: a camera 0.8 m above the board, allowed fields red, others
white, a blue box on the first red field."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
from sofia_schemas import Board, FlangePose, pointcloud
from sofia_schemas.messages import Detection
from sofia_schemas.ros2.encoding import decode_flange
from sofia_schemas.rosmsg import encode_flange_pose
from sofia_schemas.transforms import apply

from .pick import PickParams, first_pick

log = logging.getLogger(__name__)

WARM_SHAPE = (480, 640)  # rows, cols of the scene's organized cloud: the D435's usual
WARM_HEIGHT_M = 0.8  # camera above the board: all of it in view
WARM_FOCAL_PX = 500.0  # the whole board in view
WARM_BOX_M = (0.04, 0.04, 0.03)  # length, width, height of the box
RED, WHITE, BLUE = (200, 30, 30), (230, 230, 230), (30, 60, 200)


def warm_scene(board: Board) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) float32 points in the board's frame (usually the robot base), metres, and
    (H, W, 3) uint8 colours of a box on ``board``'s first red field (its centre field when none)."""
    rows, cols = WARM_SHAPE
    v, u = np.mgrid[0:rows, 0:cols].astype(np.float64)
    x = (v - (rows - 1) / 2) / WARM_FOCAL_PX * WARM_HEIGHT_M
    y = (u - (cols - 1) / 2) / WARM_FOCAL_PX * WARM_HEIGHT_M
    field = board.field_of_board_xy(np.stack([x, y], axis=-1).reshape(-1, 2)).reshape(rows, cols, 2)
    on_board = field[..., 0] >= 0
    red = np.array(
        [[board.is_allowed(r, c) for c in range(board.cols)] for r in range(board.rows)], dtype=bool
    )
    row, col = board.allowed[0] if board.allowed else (board.rows // 2, board.cols // 2)
    box_xy = board.field_centers_board()[row, col]
    in_box = (np.abs(x - box_xy[0]) < WARM_BOX_M[0] / 2) & (np.abs(y - box_xy[1]) < WARM_BOX_M[1] / 2)
    z = np.where(in_box, WARM_BOX_M[2], 0.0)
    p_board = np.stack([x, y, z], axis=-1)
    p_board[~on_board] = np.nan
    points = apply(board.T_base_board, p_board).astype(np.float32)
    rgb = np.full((rows, cols, 3), WHITE, dtype=np.uint8)
    rgb[on_board & red[field[..., 0], field[..., 1]]] = RED
    rgb[in_box] = BLUE
    return points, rgb


def warm_up(board: Board, detect_payload: Callable[[bytes, bool, str], Detection], pick: PickParams) -> float:
    """Run the per-cloud path once on :func:`warm_scene` (in the board's frame, with colours) and
    decode a flange pose, publishing nothing; seconds taken. A failure is logged, never raised."""
    t0 = time.perf_counter()
    try:
        points, rgb = warm_scene(board)
        det = detect_payload(bytes(pointcloud.encode_points(points, stamp_ns=1, frame_id=board.frame_id, rgb=rgb)),
                             False, "warm-up")  # fmt: skip
        det.to_json_bytes()
        target = first_pick(det, pick)
        if target is not None:
            target.to_json_bytes()
        pose = FlangePose(stamp_ns=1, translation=(0.0, 0.0, 0.0), rotation_xyzw=(0.0, 0.0, 0.0, 1.0))
        decode_flange(encode_flange_pose(pose)).matrix()  # imports the ROS types a callback would
    except Exception as e:  # a warm-up must not keep the service from starting
        log.warning("warm-up failed (%s: %s); the first cloud will take longer", type(e).__name__, e)
        return time.perf_counter() - t0
    took = time.perf_counter() - t0
    log.debug("warm-up: %s, %d objects, pick %s, %.0f ms", det.status, len(det.objects), target is not None,
              took * 1e3)  # fmt: skip
    return took
