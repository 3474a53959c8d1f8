"""Objects of an unorganized cloud (N x 3): connected cells of an occupancy grid in the board plane.

Flying pixels are sparse in 3D where a real surface is dense: points with fewer than
:data:`MIN_VOXEL_POINTS` in their voxel go. Pieces of one colour joined by cells without any point
(missing depth on a dark object) are one object; where the board was seen between them, two.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..depth.clean import chroma, colour_distance, label_means
from ..geometry.grid import label8, max_filter
from ..geometry.points import change_frame
from ..params import DetectorParams
from .points import ObjectPoints, inside

VOXEL = 0.005  # metres: a surface at a D435's pixel spacing (1-2 mm at 0.5-1 m) puts 5-25 points in one
MIN_VOXEL_POINTS = 3
BRIDGE_CELLS = 3  # empty cells a piece grows through to meet another piece of its colour


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


def _candidates(labels: np.ndarray, n: int, colour: np.ndarray, tol: float) -> list[tuple[int, int]]:
    """Pairs (i, j) of labels 1..n of ``labels`` (h, w) of one colour (``colour`` (n + 1, 4) chroma)
    whose bounding boxes, grown by :data:`BRIDGE_CELLS` each, meet."""
    boxes = ndimage.find_objects(labels, max_label=n)
    lo = np.array([[s[0].start, s[1].start] if s else [-9999, -9999] for s in boxes]) - BRIDGE_CELLS
    hi = np.array([[s[0].stop, s[1].stop] if s else [-9999, -9999] for s in boxes]) + BRIDGE_CELLS
    meet = np.all((lo[:, None] < hi[None]) & (lo[None] < hi[:, None]), axis=2)
    i, j = np.nonzero(np.triu(meet, 1))
    close = colour_distance(colour[i + 1], colour[j + 1]) < tol
    return list(zip((i[close] + 1).tolist(), (j[close] + 1).tolist(), strict=True))


def join_pieces(labels: np.ndarray, n: int, empty: np.ndarray, pairs: list[tuple[int, int]]) -> np.ndarray:
    """``labels`` (h, w) int (1..n) with those ``pairs`` merged that meet when each grows up to
    :data:`BRIDGE_CELLS` cells into ``empty`` (h, w) bool cells."""
    grown = labels.copy()
    for _ in range(BRIDGE_CELLS):
        around = max_filter(grown, 3)  # the largest label among the 8 neighbours (or the cell)
        step = empty & (grown == 0) & (around > 0)
        if not step.any():
            break
        grown[step] = around[step]
    wanted = set(pairs)
    links = set()
    for a, b in ((grown[:, :-1], grown[:, 1:]), (grown[:-1], grown[1:]), (grown[:-1, :-1], grown[1:, 1:]),
                 (grown[:-1, 1:], grown[1:, :-1])):  # fmt: skip
        meet = (a > 0) & (b > 0) & (a != b)
        links |= {(min(i, j), max(i, j)) for i, j in zip(a[meet].tolist(), b[meet].tolist(), strict=True)}
    i, j = np.array(sorted(links & wanted), dtype=np.intp).reshape(-1, 2).T
    graph = coo_matrix((np.ones(i.size), (i, j)), shape=(n + 1, n + 1))
    _, roots = connected_components(graph, directed=False)
    return roots[labels]  # type: ignore[no-any-return]


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
    frame. rgb: (n, 3) uint8 or None (then no :func:`join_pieces`)."""
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
    point_labels = labels.ravel()[flat]
    if rgb is not None and n >= 2:
        pairs = _candidates(labels, n, label_means(point_labels, chroma(rgb[idx]), n), params.colour_tol)
        if pairs:  # cells where the cloud has no point at all: missing depth
            seen = np.bincount(cells(np.flatnonzero(region)), minlength=counts.size).reshape(shape) > 0
            point_labels = join_pieces(labels, n, ~seen, pairs).ravel()[flat]
    order = np.argsort(point_labels, kind="stable")
    bounds = np.searchsorted(point_labels[order], np.arange(1, n + 2))
    for i in range(n):
        sel = idx[order[bounds[i] : bounds[i + 1]]]
        pts = b[:, sel]
        if pts.shape[1] == 0 or not inside(pts[:2].mean(axis=1), half):
            continue
        yield ObjectPoints(pts, point_rgb=None if rgb is None else rgb[sel])
