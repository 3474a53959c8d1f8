"""The real board from the cloud: its plane, then its position and yaw within the plane."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from sofia_schemas import Board
from sofia_schemas.transforms import invert

from ..geometry.grid import grid_boundary, largest_component
from ..geometry.points import change_frame, points_in_frame
from ..params import DetectorParams
from .grid import board_outline, plane_candidates, reach_hits
from .outline import Outline, fit_outline
from .plane import PlaneFit, T_cfg_plane, fit_plane, planar_transform

MIN_BOARD_POINTS = 50
PLANE_FIT_POINTS = 2500  # plenty: the plane offset's standard error is ~0.05 mm
OUTLINE_CELL = 0.008  # occupancy cell of the outline of unorganized clouds, metres
EDGE_REACH_PX = 2  # grid cells from the board top to the surface below its edge (stereo shadow)
EDGE_REACH_CELLS = 5  # occupancy cells: also the strip of table the board's side hides from the camera


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


def _reach_steps(reach: int) -> np.ndarray:
    """(4 reach, 2) int (row, column) steps 1..reach down, up, right and left."""
    d = np.arange(1, reach + 1)
    return np.concatenate([np.outer(d, step) for step in ((1, 0), (-1, 0), (0, 1), (0, -1))])


STEPS_PX, STEPS_CELLS = _reach_steps(EDGE_REACH_PX), _reach_steps(EDGE_REACH_CELLS)


def _grid_steps(A: np.ndarray) -> np.ndarray:
    """(2, 2) plane-frame step of one grid row (column 0) and column (column 1), metres: the affine
    fit of rows ``(row, col, 1, x, y)`` of ``A`` (k, 5) float64; the identity for collinear cells."""
    G = A[:, :3].T @ A  # the normal equations (3, 5): numpy's least-squares call costs 20x their solve
    if not abs(np.linalg.det(G[:, :3])) > 1e-12 * abs(G[0, 0] * G[1, 1] * G[2, 2]):
        return np.eye(2)
    return np.linalg.solve(G[:, :3], G[:, 3:])[:2].T  # type: ignore[no-any-return]


def _scattered_outline_points(m: np.ndarray, band: float, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2) plane-frame points on the board top's outline and the direction (not normalised) from
    each towards the cells below the top it reaches (0 where missing depth, the image border or
    something in front cuts the top short). m: (3, n) float32, plane frame, metres. The top: the
    largest patch of points within ``band`` of the plane and ``half`` (2,) of its centre on a grid
    of :data:`OUTLINE_CELL`; below it: lower than ``-band``."""
    with np.errstate(invalid="ignore"):
        top = (np.abs(m[2]) < band) & (np.abs(m[0]) < half[0]) & (np.abs(m[1]) < half[1])
        low = (m[2] < -band) & (np.abs(m[0]) < half[0]) & (np.abs(m[1]) < half[1])
    shape = tuple(np.ceil(2 * half / OUTLINE_CELL).astype(int) + 1)

    def occupancy(sel: np.ndarray) -> np.ndarray:
        idx = np.floor((m[:2, sel].T + half) / OUTLINE_CELL).astype(np.intp)
        occ = np.zeros(shape, dtype=bool)
        occ[idx[:, 0], idx[:, 1]] = True
        return occ

    comp = largest_component(occupancy(top))
    if not comp.any():
        return np.empty((0, 2)), np.empty((0, 2))
    r, c = grid_boundary(comp)
    xy = (np.stack([r, c], axis=1) + 0.5) * OUTLINE_CELL - half
    return xy, reach_hits(occupancy(low), r, c, STEPS_CELLS) @ (OUTLINE_CELL * STEPS_CELLS)


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
    if m.ndim == 3:  # the top's outline on every second cell of the grid (plenty)
        outline_xy, A, hits = board_outline(m, params.outline_band, half[0], half[1], STEPS_PX)
        drop_xy = hits @ (STEPS_PX @ _grid_steps(A).T)  # towards the cells below the board top
    else:
        outline_xy, drop_xy = _scattered_outline_points(m, params.outline_band, half)
    if outline_xy.shape[0] < 8:  # too little of the board top: it lies where it is configured
        return BoardFit(T_base_plane.copy(), T_base_plane, plane, None, m)
    outline = fit_outline(outline_xy, board.extent, params.max_board_yaw, params.max_rim, drop_xy)
    T_plane_board = planar_transform(*outline.center, outline.yaw)
    return BoardFit(T_base_plane @ T_plane_board, T_base_plane, plane, outline, m)
