"""Warm the detector service before its first cloud: compiled kernels, lazy imports, first calls.

Without it the first detection took 60-110 ms (numba's cache, first calls, the import of the
flange pose's CDR types under the GIL) and, at 30 Hz with a backlog of one, the next cloud was
dropped. The service runs its whole per-cloud path once on :func:`warm_payloads` (a scene of the
configured board seen from 0.8 m above, a blue box on the first red field, and a flange pose).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
from sofia_schemas import Board, FlangePose, pointcloud
from sofia_schemas.messages import Detection
from sofia_schemas.ros2.encoding import decode_flange
from sofia_schemas.rosmsg import encode_flange_pose

from .board.plane import fit_plane
from .depth.clean import bridge, consistent_at
from .geometry.points import change_frame, points_in_frame
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
    red = np.zeros((board.rows, board.cols), dtype=bool)
    for r, c in board.allowed:
        red[r, c] = True
    row, col = board.allowed[0] if board.allowed else (board.rows // 2, board.cols // 2)
    box_xy = board.field_centers_board()[row, col]
    in_box = (np.abs(x - box_xy[0]) < WARM_BOX_M[0] / 2) & (np.abs(y - box_xy[1]) < WARM_BOX_M[1] / 2)
    z = np.where(in_box, WARM_BOX_M[2], 0.0)
    p_board = np.stack([x, y, z], axis=-1)
    p_board[~on_board] = np.nan
    T = board.T_base_board
    points = (p_board @ T[:3, :3].T + T[:3, 3]).astype(np.float32)
    rgb = np.empty((rows, cols, 3), dtype=np.uint8)
    rgb[:] = WHITE
    rgb[on_board & red[field[..., 0], field[..., 1]]] = RED
    rgb[in_box] = BLUE
    return points, rgb


def compile_kernels() -> None:
    """Compile every kernel of the detector (or load it from numba's cache) for the argument
    layouts a detection passes (a received cloud's read-only, strided views of its bytes; arrays;
    every k-th pixel), so that no detection waits for numba (``scripts/install.sh``, the detector's
    image, the service's warm-up)."""
    two = np.zeros((6, 6), dtype=bool)
    two[1, 1] = two[4, 4] = True  # two components
    xyz = np.zeros((3, 6, 6), dtype=np.float32)
    change_frame(xyz, np.eye(4))
    consistent_at(xyz, two, 0.01)
    x, y = (v.ravel().astype(np.float32) for v in np.mgrid[0:6, 0:6])
    fit_plane(x, y, np.zeros_like(x), (0.01,), 3)
    received = np.frombuffer(bytes(6 * 6 * 16), dtype=np.float32).reshape(6, 6, 4)  # x, y, z, bgr0
    plain = np.frombuffer(bytes(6 * 6 * 12), dtype=np.float32).reshape(6, 6, 3)  # without colours
    for points in (received[..., :3], plain, xyz.transpose(1, 2, 0).copy(), xyz.transpose(1, 2, 0)[:, ::2]):
        points_in_frame(points, np.eye(4))
    received_rgb = received.view(np.uint8).reshape(6, 6, 16)[..., 14:11:-1]
    for colours in (received_rgb, np.zeros((6, 12, 3), dtype=np.uint8)[:, ::2]):
        bridge(two, ~two, colours, 0.25)


def warm_payloads(board: Board) -> tuple[bytearray, bytes]:
    """CDR PointCloud2 of :func:`warm_scene` (in the board's frame, with colours) and CDR
    TransformStamped of an identity flange pose; the kernels compiled or loaded first."""
    compile_kernels()
    points, rgb = warm_scene(board)
    cloud = pointcloud.encode_points(points, stamp_ns=1, frame_id=board.frame_id, rgb=rgb)
    pose = FlangePose(stamp_ns=1, translation=(0.0, 0.0, 0.0), rotation_xyzw=(0.0, 0.0, 0.0, 1.0))
    return cloud, encode_flange_pose(pose)


def warm_up(board: Board, detect_payload: Callable[[bytes, bool, str], Detection], pick: PickParams) -> float:
    """Run the service's per-cloud path once on :func:`warm_payloads`, publishing nothing: decode
    and detect (``detect_payload``, the service's), the messages' JSON, the pick, a flange pose's
    decode. Seconds taken. A failure is logged, never raised: the service starts anyway, and only
    its first cloud is slower."""
    t0 = time.perf_counter()
    try:
        cloud, flange = warm_payloads(board)
        det = detect_payload(bytes(cloud), False, "warm-up")
        det.to_json_bytes()
        target = first_pick(det, pick)
        if target is not None:
            target.to_json_bytes()
        decode_flange(flange).matrix()
    except Exception as e:  # a warm-up must not keep the service from starting
        log.warning("warm-up failed (%s: %s); the first cloud will take longer", type(e).__name__, e)
        return time.perf_counter() - t0
    took = time.perf_counter() - t0
    log.debug("warm-up: %s, %d objects, pick %s, %.0f ms", det.status, len(det.objects), target is not None,
              took * 1e3)  # fmt: skip
    return took
