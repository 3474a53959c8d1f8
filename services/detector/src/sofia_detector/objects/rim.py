"""Round flat tops (cylinders, pucks) centred by a circle through the seen rim pixels that border
the board or the object's side; a box's rim lies closer to its rectangle. A top out of view: the
upright round side gives the axis (:func:`round_side`)."""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from ..geometry.grid import grow, where
from ..geometry.rect import Rect
from ..geometry.samples import median
from ..segment.points import ObjectPoints

MIN_RIM = 12  # fewest rim pixels for a circle
MAX_GAP = np.deg2rad(290.0)  # widest angle around the centre without rim pixels
CAP_SHARE = 0.3  # a flat top of less than this share of the object's footprint is a cap on a body
WHOLE_TOP = 0.003  # a top whose rectangle matches its circle this well is seen whole, metres
RMS_SPACINGS = 0.8  # largest rms radial residual, in pixel spacings (plus the depth noise)
SIDE_BAND = (0.2, 0.7)  # share of the highest point between which a round side is fitted
SIDE_RMS = 0.001  # largest rms radial residual of a round side, metres (plus the depth noise)
SIDE_ARC = np.deg2rad(100.0)  # narrowest arc of a round side around its axis
SIDE_KEEP = 0.8  # least share of the side's points on its circle


def rim_xy(obj: ObjectPoints, face: np.ndarray, top: float, drop: float) -> tuple[np.ndarray, float]:
    """((k, 2) board-frame xy, pixel spacing) of the rim pixels of the top ``face`` ((n,) bool) whose
    neighbours off it all lie more than ``drop`` below ``top`` (metres): edges against the board or
    its sides, not against missing depth, the image border or something higher."""
    if obj.rows is None or obj.cols is None or obj.window is None:
        return np.zeros((0, 2)), 0.0
    fr, fc = obj.rows[face], obj.cols[face]
    if fr.size == 0:
        return np.zeros((0, 2)), 0.0
    # the top's bounding box and one pixel around it
    r0, c0 = max(int(fr.min()) - 1, 0), max(int(fc.min()) - 1, 0)
    r1, c1 = min(int(fr.max()) + 2, obj.shape[0]), min(int(fc.max()) + 2, obj.shape[1])
    grid = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    grid[fr - r0, fc - c0] = True
    r, c = _rim_pixels(ndimage.binary_fill_holes(grid), obj.window[2, r0:r1, c0:c1], top - drop)
    xy = obj.window[:2, r + r0, c + c0].T.astype(np.float64)
    # pixel spacing: a sample of the top's pixels and their right-hand neighbours
    k = max(1, fr.size // 200)
    sr, sc = fr[::k], np.minimum(fc[::k] + 1, obj.shape[1] - 1)
    with np.errstate(over="ignore", invalid="ignore"):  # huge coordinates: no spacing
        step = obj.window[:2, sr, sc] - obj.window[:2, fr[::k], fc[::k]]
        d = np.hypot(step[0], step[1])
    d = d[np.isfinite(d) & (d > 0)]
    spacing = float(median(d)) if d.size else 0.002
    return xy[np.isfinite(xy).all(axis=1)], spacing


def _rim_pixels(grid: np.ndarray, h: np.ndarray, below: float) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) (k,) of the pixels of ``grid`` (h, w) bool with a neighbour off it whose 3 x 3
    neighbourhood is the top or lower than ``below`` (heights h (h, w) float32, NaN: unseen)."""
    with np.errstate(invalid="ignore"):
        higher = ~grid & ~(h < below)  # off the top and not lower (NaN: unseen)
    rim = grid & grow(~grid, 3) & ~grow(higher, 3)
    rim[[0, -1]], rim[:, [0, -1]] = False, False  # a pixel on the box's border has unseen neighbours
    return where(rim)


def fit_circle(xy: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(centre (2,), radius, rms radial residual) of the algebraic least-squares circle through xy
    (k, 2), k >= 3; radius and rms inf for collinear points."""
    xy = np.asarray(xy, dtype=np.float64)
    m = xy.mean(axis=0)
    uv = (xy - m).T  # (2, k)
    M = uv @ uv.T
    if M[0, 0] * M[1, 1] - M[0, 1] ** 2 <= 1e-12 * np.trace(M) ** 2:
        return m, math.inf, math.inf  # collinear points
    A = np.vstack([uv, np.ones(uv.shape[1])])
    sol = np.linalg.solve(A @ A.T, A @ -(uv * uv).sum(axis=0))
    c = -sol[:2] / 2
    r = math.sqrt(max(float(c @ c - sol[2]), 0.0))
    rms = float(np.sqrt(np.mean((np.hypot(*(uv - c[:, None])) - r) ** 2)))
    return c + m, r, rms


def widest_gap(xy: np.ndarray, center: np.ndarray) -> float:
    """Widest angle (radians) around ``center`` (2,) without any of xy (k, 2), k >= 1."""
    ang = np.sort(np.arctan2(xy[:, 1] - center[1], xy[:, 0] - center[0]))
    return float(np.diff(np.append(ang, ang[0] + 2 * np.pi)).max())


def round_top(
    obj: ObjectPoints, face: np.ndarray, top: float, noise: float, rect: Rect
) -> tuple[np.ndarray, float] | None:
    """(centre (2,), radius) of a round flat top ``face`` at height ``top`` from its rim
    (:func:`rim_xy`), or None: the rim (without outliers) on a circle within about a pixel, closer
    than on ``rect`` (the seen top, which the circle holds), no gap wider than :data:`MAX_GAP`."""
    xy, spacing = rim_xy(obj, face, top, max(3 * noise, 0.004))
    if len(xy) < MIN_RIM:
        return None
    center, r, _ = fit_circle(xy)
    res = np.abs(np.hypot(xy[:, 0] - center[0], xy[:, 1] - center[1]) - r)
    keep = res <= max(4.5 * float(median(res)), 0.5 * spacing)
    if np.count_nonzero(keep) < max(MIN_RIM, 0.8 * len(xy)):
        return None
    xy = xy[keep]
    center, r, rms = fit_circle(xy)
    pixel = min(spacing, 0.003)
    if not np.isfinite(r) or r < 0.005 or rms > RMS_SPACINGS * pixel + noise:
        return None
    uv = xy @ rect.R  # in the rectangle's axes: the distance to its nearest side
    d = np.minimum(np.abs(uv - rect.lo), np.abs(uv - rect.hi)).min(axis=1)
    if float(rect.size.max()) > 2 * r + 2 * pixel + 0.002 or rms > 0.5 * float(np.sqrt(np.mean(d * d))):
        return None  # the seen top does not fit in the circle, or it is a rectangle
    if widest_gap(xy, center) > MAX_GAP:
        return None
    return center, r


def round_footprint(
    obj: ObjectPoints, face: np.ndarray, top: float, noise: float, rect: Rect, whole: Rect
) -> tuple[np.ndarray, float] | None:
    """(centre (2,), radius) of a round object whose top's rectangle ``rect`` is cut short, or None
    (not round, or ``rect`` is the whole top: then its centre is better). A top much smaller than
    ``whole`` (all the points) is a cap on a wider body: the body's outline gives the centre."""
    if float(np.prod(rect.size)) < CAP_SHARE * float(np.prod(whole.size)):
        return round_top(obj, np.ones_like(face), top, noise, whole)
    if abs(float(rect.size[0] - rect.size[1])) < WHOLE_TOP:
        return None  # a square: a round top seen whole, or a square top
    circle = round_top(obj, face, top, noise, rect)
    if circle is None or np.all(np.abs(rect.size - 2 * circle[1]) < WHOLE_TOP):
        return None
    return circle


def round_side(b: np.ndarray, noise: float, h_hi: float) -> tuple[np.ndarray, float] | None:
    """(centre_xy (2,), radius) of the circle through an upright round side, or None: the xy of b
    (3, n) between :data:`SIDE_BAND` of the highest ``h_hi``, refitted on those within two noise
    deviations plus 2 mm; :data:`SIDE_KEEP` of them, rms :data:`SIDE_RMS` plus the noise, around
    an arc of :data:`SIDE_ARC` or more (a flat face fits only a short arc)."""
    h = b[2]
    sel = (h > SIDE_BAND[0] * h_hi) & (h < SIDE_BAND[1] * h_hi)
    if np.count_nonzero(sel) < 30:
        return None
    xy = b[:2, sel].T.astype(np.float64)
    keep = np.ones(xy.shape[0], dtype=bool)
    for _ in range(3):
        c, r, _ = fit_circle(xy[keep])
        if not np.isfinite(r) or r <= 0:
            return None
        keep = np.abs(np.hypot(*(xy - c).T) - r) < 2 * noise + 0.002
        if np.count_nonzero(keep) < SIDE_KEEP * xy.shape[0]:
            return None
    c, r, rms = fit_circle(xy[keep])
    if rms > SIDE_RMS + noise or 2 * np.pi - widest_gap(xy[keep], c) < SIDE_ARC:
        return None
    return c, r
