"""Objects of an unorganized cloud (N x 3): connected cells of an occupancy grid in the board plane.

Flying pixels are sparse in 3D where a real surface is dense: points with fewer than
:data:`MIN_VOXEL_POINTS` in their voxel go. Pieces of one colour joined by cells without any point
(missing depth on a dark object) are one object; where the board was seen between them, two.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from scipy import ndimage

from ..depth.clean import chroma, join_pieces, label_means
from ..geometry.grid import label8
from ..geometry.points import change_frame
from ..params import DetectorParams
from .points import ObjectPoints

VOXEL = 0.005  # metres: a surface at a D435's pixel spacing (1-2 mm at 0.5-1 m) puts 5-25 points in one
MIN_VOXEL_POINTS = 3


def dense(b: np.ndarray, voxel: float = VOXEL, k: int = MIN_VOXEL_POINTS) -> np.ndarray:
    """(n,) bool: points of b (3, n) (metres, finite) with ``k`` points or more in their voxel."""
    if b.shape[1] == 0:
        return np.zeros(0, dtype=bool)
    key = np.floor(b / voxel).astype(np.int64)
    key -= key.min(axis=1, keepdims=True)
    dims = key.max(axis=1) + 1
    flat = (key[0] * dims[1] + key[1]) * dims[2] + key[2]
    _, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
    return counts[inverse] >= k  # type: ignore[no-any-return]


def unorganized_objects(
    m_plane: np.ndarray,
    T_plane_board: np.ndarray,
    half: np.ndarray,
    params: DetectorParams,
    point: float,
    rgb: np.ndarray | None = None,
) -> Iterator[ObjectPoints]:
    """Objects of m_plane (3, n) float32, plane frame, metres: points more than ``point`` above
    the board on a dense surface (:func:`dense`), in cells of ``params.cell`` holding two or more,
    connected. T_plane_board: (4, 4). half: (2,) half size of the region of object centres, board
    frame. rgb: (n, 3) uint8 or None (then no :func:`..depth.clean.join_pieces`)."""
    b = change_frame(m_plane, T_plane_board)
    grid_half = half + 0.06
    with np.errstate(invalid="ignore"):
        region = (np.abs(b[0]) < grid_half[0]) & (np.abs(b[1]) < grid_half[1])
        up = region & (b[2] > point) & (b[2] < params.max_height)
    idx = np.flatnonzero(up)
    idx = idx[dense(b[:, idx])]
    if idx.size == 0:
        return
    shape = tuple(np.ceil(2 * grid_half / params.cell).astype(int) + 1)

    def cells(i: np.ndarray) -> np.ndarray:
        ij = np.floor((b[:2, i].T + grid_half) / params.cell).astype(np.intp)
        return np.ravel_multi_index((ij[:, 0], ij[:, 1]), shape)  # type: ignore[no-any-return]

    flat = cells(idx)
    counts = np.bincount(flat, minlength=shape[0] * shape[1]).reshape(shape)
    labels, n = label8(counts >= 2)
    if rgb is not None and n >= 2:  # joined through cells where the cloud has no point: missing depth
        seen = np.bincount(cells(np.flatnonzero(region)), minlength=counts.size).reshape(shape) > 0
        mean = label_means(labels.ravel()[flat], chroma(rgb[idx]), n)
        labels, n = join_pieces(labels, n, ~seen, mean, params.colour_tol)
    for at in ndimage.value_indices(labels.ravel()[flat], ignore_value=0).values():
        sel = idx[at[0]]
        pts = b[:, sel]
        if not np.all(np.abs(pts[:2].mean(axis=1)) < half):  # off the board
            continue
        yield ObjectPoints(pts, point_rgb=None if rgb is None else rgb[sel])
