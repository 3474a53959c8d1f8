"""An object with depth on a sliver only, placed from its colour silhouette: its rays (a pinhole
camera fitted to the cloud around it) cut the plane of its top (the slivers' height) and the board
in two regions whose intersection is the footprint of vertical sides."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..depth.clean import EIGHT, median_chroma, of_colour
from ..geometry.grid import grow, label8, where
from ..geometry.points import points_in_frame
from ..geometry.rect import Rect, min_area_rect
from ..geometry.samples import median
from ..segment.points import ObjectPoints
from .holes import BOARD_LIKE, RAISED

MIN_MISSING = 0.5  # share of the silhouette without depth below which the slivers are the object
CAMERA_POINTS = 600  # pixels with depth used to fit the camera
MAX_REPROJECTION = 1.5  # pixels: median reprojection error of a usable camera fit
CELL = 0.002  # metres: grid of the ray intersections
ON_FOOTPRINT = 0.004  # metres: the slivers lie on the footprint within this distance


@dataclass(frozen=True)
class Silhouette:
    """Pixels (rows, cols) (n,) in the image, their share without depth, the board-frame footprint
    (None when it cannot be placed)."""

    rows: np.ndarray
    cols: np.ndarray
    missing: float
    rect: Rect | None = None


def _normalising(p: np.ndarray) -> np.ndarray:
    """(d + 1, d + 1) Hartley conditioning of p (n, d): centroid 0, mean distance sqrt(d)."""
    d, m = p.shape[1], p.mean(axis=0)
    s = np.sqrt(d) / max(float(np.mean(np.linalg.norm(p - m, axis=1))), 1e-12)
    T = np.diag([s] * d + [1.0])
    T[:d, d] = -s * m
    return T


def fit_camera(pix: np.ndarray, xyz: np.ndarray) -> np.ndarray | None:
    """(3, 4) P with ``P [xyz 1]^T ~ [pix 1]^T`` by the normalised direct linear transform (OpenCV
    fits homographies, not projections) of pix (n, 2) (col, row) and xyz (n, 3) (board frame,
    metres, not coplanar); None when they do not fix it or it reprojects them worse than
    :data:`MAX_REPROJECTION`."""
    if pix.shape[0] < 12 or float(np.std(xyz[:, 2])) < 0.005:
        return None
    Ts, Td = _normalising(xyz), _normalising(pix)
    X = np.hstack([xyz, np.ones((len(xyz), 1))]) @ Ts.T
    u, v = (np.hstack([pix, np.ones((len(pix), 1))]) @ Td.T)[:, :2].T
    zero = np.zeros_like(X)
    A = np.vstack([np.hstack([X, zero, -u[:, None] * X]), np.hstack([zero, X, -v[:, None] * X])])
    _, s, vt = np.linalg.svd(A, full_matrices=False)
    if s[-2] < 1e-9 * s[0]:
        return None
    P = np.linalg.inv(Td) @ vt[-1].reshape(3, 4) @ Ts
    q = P @ np.hstack([xyz, np.ones((xyz.shape[0], 1))]).T
    err = np.linalg.norm(q[:2] / q[2] - pix.T, axis=0)
    return P if float(median(err)) < MAX_REPROJECTION else None


def on_plane(P: np.ndarray, cols: np.ndarray, rows: np.ndarray, z: float) -> np.ndarray:
    """(n, 2) board-frame xy where the rays of pixels (cols, rows) (n,) cut the plane at height z."""
    H = np.column_stack([P[:, 0], P[:, 1], P[:, 2] * z + P[:, 3]])
    q = np.linalg.solve(H, np.vstack([cols, rows, np.ones(cols.size)]))
    return (q[:2] / q[2]).T  # type: ignore[no-any-return]


def _cells(xy: np.ndarray, lo: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(shape) bool: cells of :data:`CELL` from ``lo`` holding a point of xy (n, 2), closed, filled."""
    idx = np.floor((xy - lo) / CELL).astype(np.intp)
    grid = np.zeros(shape, dtype=bool)
    grid[idx[:, 0], idx[:, 1]] = True
    return ndimage.binary_fill_holes(ndimage.binary_closing(grid, EIGHT, iterations=2, border_value=0))


def footprint(P: np.ndarray, rows: np.ndarray, cols: np.ndarray, height: float) -> np.ndarray:
    """(k, 2) board-frame cell centres where the rays of pixels (rows, cols) (n,) at ``height`` and at
    the board agree: the footprint of an upright object."""
    top = on_plane(P, cols, rows, height)
    base = on_plane(P, cols, rows, 0.0)
    lo = np.minimum(top.min(axis=0), base.min(axis=0)) - 3 * CELL
    hi = np.maximum(top.max(axis=0), base.max(axis=0)) + 3 * CELL
    shape = tuple(np.ceil((hi - lo) / CELL).astype(int) + 1)
    both = _cells(top, lo, shape) & _cells(base, lo, shape)  # type: ignore[arg-type]
    i, j = where(both)
    return lo + (np.column_stack([i, j]) + 0.5) * CELL  # type: ignore[no-any-return]


def silhouette(
    obj: ObjectPoints, cloud: np.ndarray, rgb: np.ndarray, T_base_board: np.ndarray, height: float, tol: float
) -> Silhouette | None:
    """The object whose depth is only the sliver ``obj``: the region of its colour (within ``tol``)
    joined to it, without depth or raised, within one window size around it. cloud: (H, W, 3),
    base frame, metres; rgb: (H, W, 3) uint8; height: its top above the board, metres.

    None when the board around has its colour; no ``rect`` when the region reaches the searched
    area's edge, depth covers most of it, the camera or footprint is not fixed, or the slivers are
    off the footprint.
    """
    if obj.rows is None or obj.cols is None or obj.rgb is None:
        return None
    (r0, c0), (H, W) = obj.origin, obj.image_shape
    h, w = obj.shape
    top, bottom = max(r0 - h, 0), min(r0 + 2 * h, H)
    left, right = max(c0 - w, 0), min(c0 + 2 * w, W)
    b = points_in_frame(cloud[top:bottom, left:right], T_base_board)
    z = b[2]
    rows, cols = obj.rows + r0 - top, obj.cols + c0 - left
    own = median_chroma(obj.rgb, obj.rows, obj.cols)
    same = of_colour(rgb[top:bottom, left:right], own, tol)
    with np.errstate(invalid="ignore"):
        board = np.abs(z) < RAISED
    around = board & grow(same, 9)
    if np.count_nonzero(same & around) > BOARD_LIKE * max(int(np.count_nonzero(around)), 1):
        return None  # the object stands on its own colour
    labels, _ = label8(same & ~board)
    ids = np.unique(labels[rows, cols])
    region = np.isin(labels, ids[ids > 0])
    region[rows, cols] = True
    sr, sc = where(region)
    missing = float(np.mean(np.isnan(z[sr, sc])))
    unplaced = Silhouette(sr + top, sc + left, missing)
    edge = (sr == 0) | (sc == 0) | (sr == z.shape[0] - 1) | (sc == z.shape[1] - 1)
    if edge.any() or missing < MIN_MISSING:
        return unplaced
    vr, vc = where(np.isfinite(z))
    k = max(1, vr.size // CAMERA_POINTS)
    vr, vc = vr[::k], vc[::k]
    P = fit_camera(
        np.column_stack([vc + left, vr + top]).astype(np.float64), b[:, vr, vc].T.astype(np.float64)
    )
    if P is None:
        return unplaced
    cells = footprint(P, sr + top, sc + left, height)
    if cells.shape[0] < 3:
        return unplaced
    rect = min_area_rect(cells)
    # the slivers are the object's top or sides: on its footprint
    inside = np.abs((obj.b[:2].T - rect.center) @ rect.R) <= rect.size / 2 + ON_FOOTPRINT
    if np.mean(np.all(inside, axis=1)) < 0.5:
        return unplaced
    return Silhouette(sr + top, sc + left, missing, rect)
