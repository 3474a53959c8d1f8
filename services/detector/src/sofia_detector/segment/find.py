"""``find_objects``: the points of every object of one cloud and its thresholds (:class:`.points.Levels`)."""

from __future__ import annotations

import numpy as np
from sofia_schemas import Board
from sofia_schemas.transforms import invert

from ..board import BoardFit
from ..depth.clean import pixel_spacing
from ..params import DetectorParams
from .organized import organized_objects
from .points import Levels, ObjectPoints
from .unorganized import unorganized_objects


def levels(fit: BoardFit, params: DetectorParams, organized: bool) -> Levels:
    """Thresholds of one cloud from the board's fitted noise and (organized) pixel spacing."""
    noise = fit.plane.rms if np.isfinite(fit.plane.rms) else 0.002
    spacing = pixel_spacing(fit.m_coarse, params.stride) if organized else params.cell
    return Levels(
        seed=max(params.seed_height, params.noise_k * noise),
        point=max(params.object_height, params.point_k * noise),
        delta=params.neighbour_px * spacing + 3 * noise,
        delta_coarse=2 * params.stride * spacing + 4 * noise,
    )


def find_objects(
    cloud: np.ndarray, rgb: np.ndarray | None, fit: BoardFit, board: Board, params: DetectorParams
) -> list[ObjectPoints]:
    """The points of each object on the board: cloud (H, W, 3) or (N, 3) float, base frame, metres,
    NaN allowed; rgb uint8 of cloud's shape, or None; fit: the measured board."""
    organized = cloud.ndim == 3
    lv = levels(fit, params, organized)
    half = np.array(board.extent) / 2 + params.field_margin
    if organized:
        return list(
            organized_objects(cloud, fit.m_coarse, fit.T_base_board, fit.T_board_plane, half, params, lv, rgb)
        )
    return list(unorganized_objects(fit.m_coarse, invert(fit.T_board_plane), half, params, lv.point, rgb))
