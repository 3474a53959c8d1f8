"""The real board from the cloud: its plane, then its position and yaw within the plane."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from sofia_schemas import Board
from sofia_schemas.transforms import invert

from ..geometry.points import change_frame, points_in_frame
from ..params import DetectorParams
from .grid import outline_points, plane_candidates
from .outline import Outline, fit_outline
from .plane import PlaneFit, T_cfg_plane, fit_plane, planar_transform

MIN_BOARD_POINTS = 50
PLANE_FIT_POINTS = 2500  # plenty: the plane offset's standard error is ~0.05 mm


@dataclass(frozen=True)
class BoardFit:
    """The measured board: T_base_board (4, 4), origin at the board centre on its surface, z along
    the measured normal, x along the board rows; T_base_plane (4, 4) (:mod:`.plane`); outline None
    when too little of the board top was seen; m_coarse (3, ...) float32 coarse points, plane
    frame, metres."""

    T_base_board: np.ndarray
    T_base_plane: np.ndarray
    plane: PlaneFit
    outline: Outline | None
    m_coarse: np.ndarray

    @cached_property
    def T_board_plane(self) -> np.ndarray:
        """(4, 4) the plane frame in the measured board frame."""
        return invert(self.T_base_board) @ self.T_base_plane  # type: ignore[no-any-return]


def fit_board(coarse_base: np.ndarray, board: Board, params: DetectorParams) -> BoardFit | None:
    """The board measured from coarse_base (h, w, 3) or (n, 3) float points (any strides), base
    frame, metres, NaN allowed; None when fewer than :data:`MIN_BOARD_POINTS` lie near it."""
    q = points_in_frame(coarse_base, board.T_base_board)
    ex, ey = board.extent
    lim_x, lim_y = (e / 2 - params.board_shrink for e in (ex, ey))
    qf = plane_candidates(q.reshape(3, -1), lim_x, lim_y, params.board_band, PLANE_FIT_POINTS)
    plane = fit_plane(qf[0], qf[1], qf[2], params.plane_thresholds, MIN_BOARD_POINTS)
    if plane is None:
        return None
    T_cp = T_cfg_plane(plane)
    T_base_plane = board.T_base_board @ T_cp
    m = change_frame(q, T_cp)
    half = np.array([ex / 2, ey / 2]) + params.outline_margin
    coarse = m[:, ::2, ::2] if m.ndim == 3 else m  # every second cell of a grid: plenty
    outline_xy, drop_xy = outline_points(coarse.reshape(3, -1), params.outline_band, half)
    if outline_xy.shape[0] < 8:  # too little of the board top: it lies where it is configured
        return BoardFit(T_base_plane.copy(), T_base_plane, plane, None, m)
    outline = fit_outline(outline_xy, board.extent, params.max_board_yaw, params.max_rim, drop_xy)
    T_plane_board = planar_transform(*outline.center, outline.yaw)
    return BoardFit(T_base_plane @ T_plane_board, T_base_plane, plane, outline, m)
