"""Stage 3, segmentation: the points of each object (:func:`find_objects`)."""

from __future__ import annotations

import numpy as np
from sofia_schemas import Board
from sofia_schemas.transforms import invert

from ..board import BoardFit
from ..params import DetectorParams
from .organized import organized_objects
from .points import ObjectPoints
from .unorganized import unorganized_objects

__all__ = ["ObjectPoints", "find_objects"]


def find_objects(
    cloud: np.ndarray, rgb: np.ndarray | None, fit: BoardFit, board: Board, params: DetectorParams
) -> list[ObjectPoints]:
    """The points of each object on the board: cloud (H, W, 3) or (N, 3) float, base frame, metres,
    NaN allowed; rgb uint8 of cloud's shape, or None; fit: the measured board. Heights above the
    board count from floors raised by the board's fitted depth noise."""
    noise = fit.plane.rms if np.isfinite(fit.plane.rms) else 0.002
    point = max(params.object_height, params.point_k * noise)  # height of an object's point (metres)
    half = np.array(board.extent) / 2 + params.field_margin  # the region of object centres, board frame
    if cloud.ndim == 3:
        return list(organized_objects(cloud, fit, half, params, point, noise, rgb))
    return list(unorganized_objects(fit.m_coarse, invert(fit.T_board_plane), half, params, point, rgb))
