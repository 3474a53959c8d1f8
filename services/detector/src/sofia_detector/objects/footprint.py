"""One object from its points: the footprint (vertical sides project onto it: the least-area
rectangle of the points), the top's height, and a curved top centred on its cap's apex."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.grid import label_sizes
from ..geometry.rect import min_area_rect
from ..geometry.samples import median
from ..params import DetectorParams
from ..segment.points import ObjectPoints
from .caps import fit_cone_apex, fit_top
from .holes import unseen_top
from .rim import round_footprint, round_side

FIT_POINTS = 3000  # points used by the fits (every k-th of a large object)
FLAT_K, FLAT_MIN = 3.0, 0.001  # a top whose heights spread more (noise units + metres) is no flat face
NARROW_TOP = 0.3  # share of the points in the top band below which the object may be a cone


@dataclass(frozen=True)
class ObjectEstimate:
    """An object, board frame (metres, radians): footprint centre (2,), top height, (length, width)
    and yaw of the length axis, centroid (3,) of the points, curved (a cap); whole_xy, whole_size:
    the rectangle around all its points (or an upright round side's circle, :func:`round_side`),
    what is left of an object whose top is out of view."""

    center_xy: np.ndarray
    height: float
    size: tuple[float, float]
    yaw: float
    centroid: np.ndarray
    curved: bool
    n_points: int
    whole_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    whole_size: tuple[float, float] = (0.0, 0.0)

    def covers(self, xy: np.ndarray) -> bool:
        """Whether the board-frame point xy (2,) lies on the footprint."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        d = xy - self.center_xy
        return bool(
            abs(c * d[0] + s * d[1]) < self.size[0] / 2 and abs(c * d[1] - s * d[0]) < self.size[1] / 2
        )


def half_turn(yaw: float) -> float:
    """The direction of an axis, ``yaw`` (radians) wrapped to [-pi/2, pi/2)."""
    return float((yaw + np.pi / 2) % np.pi - np.pi / 2)


def length_first(size: np.ndarray, yaw: float) -> tuple[tuple[float, float], float]:
    """((length, width), length axis direction) of a rectangle of ``size`` (2,) whose first axis
    lies at ``yaw``."""
    if size[0] < size[1]:
        return (float(size[1]), float(size[0])), half_turn(yaw + np.pi / 2)
    return (float(size[0]), float(size[1])), half_turn(yaw)


def _solid(obj: ObjectPoints, subset: np.ndarray) -> np.ndarray:
    """``subset`` ((n,) bool) without its specks on the pixel grid (mixed pixels): the pieces
    smaller than 10 % of the largest and than 10 pixels."""
    if obj.rows is None or obj.cols is None or np.count_nonzero(subset) < 3:
        return subset
    grid = np.zeros(obj.shape, dtype=bool)
    grid[obj.rows[subset], obj.cols[subset]] = True
    labels, n, sizes = label_sizes(grid)
    if n < 2:
        return subset
    largest = sizes[1:].max()
    return subset & (sizes[labels[obj.rows, obj.cols]] >= min(max(10.0, 0.1 * largest), largest))  # type: ignore[no-any-return]


def estimate_object(obj: ObjectPoints, noise: float, params: DetectorParams) -> ObjectEstimate:
    """Footprint, height and centre of one object (board frame, metres; noise: the depth noise). The
    top fit takes the points in the ellipse inscribed in 70 % of the footprint; the top is a cap when
    ``d < -params.curvature`` (1/m) with t < -4, or its heights spread beyond the noise. A cone is
    centred on its apex. A flat top's footprint: its points within 3 sigma of its height, and
    (``params.colour_tol`` > 0) missing depth of its colour (:mod:`.holes`). A top narrower than
    ``params.min_width`` is a sliver: an upright round side then gives ``whole_xy``, ``whole_size``."""
    b_all = obj.b
    n = b_all.shape[1]
    b = b_all[:, :: max(1, n // FIT_POINTS)]  # plenty for the fits
    h = b[2]
    k = max(h.size - 1 - h.size // 100, 0)
    h_hi = float(np.partition(h, k)[k])  # 99th percentile
    depth = min(max(0.14 * h_hi, 0.004), 0.012)
    rect = min_area_rect(obj.boundary_xy())
    R = rect.R
    mid, half = (rect.lo + rect.hi) / 2, np.maximum(rect.size / 2, 1e-4)
    u = ((R[0, 0] * b[0] + R[1, 0] * b[1]) - mid[0]) / half[0]
    v = ((R[0, 1] * b[0] + R[1, 1] * b[1]) - mid[1]) / half[1]
    inner = (h > h_hi - 2.3 * noise - depth) & (u * u + v * v < 0.49)
    top = b[:, inner]
    mean_top = top[:2].mean(axis=1, dtype=np.float64) if top.shape[1] else R @ mid
    fit = fit_top(top[0] - mean_top[0], top[1] - mean_top[1], top[2])
    curved, tip = False, None
    yaw, whole = rect.yaw, rect
    # a flat top's points lie within the depth noise of its height (robust deviation: 1.4826 median
    # absolute deviation); a tip's spread over the band
    spread = float(1.4826 * median(np.abs(top[2] - median(top[2])))) if top.shape[1] >= 3 else 0.0
    flat = spread < FLAT_K * noise + FLAT_MIN
    narrow = np.count_nonzero(inner) < NARROW_TOP * h.size  # a tip, or a top cut short by holes
    cone = None if flat and not narrow else fit_cone_apex(b, noise)
    if cone is not None:  # a cone: its apex, its base around it
        curved, height, center_xy, size = True, cone[1], cone[0], np.full(2, 2 * cone[2])
    elif fit is not None and fit[0][3] < -params.curvature and (fit[0][3] < -4 * fit[1] or not flat):
        coef = fit[0]
        apex = mean_top - coef[1:3] / (2 * coef[3])
        apex_uv = R.T @ apex
        if np.all((apex_uv > rect.lo) & (apex_uv < rect.hi)):
            tip = float(coef[0] - (coef[1] ** 2 + coef[2] ** 2) / (4 * coef[3]))
            if coef[3] < -4 * fit[1]:  # else a cap too sparse to place its apex: its height only
                curved, height = True, tip
                center_xy, size = apex, 2 * np.maximum(apex_uv - rect.lo, rect.hi - apex_uv)
    if not curved:
        height = float(median(top[2])) if top.shape[1] else h_hi
        face = _solid(obj, b_all[2] > height - max(3 * noise, 0.004))
        if np.count_nonzero(face) >= 3:
            unseen = unseen_top(obj, face, params.colour_tol) if params.colour_tol > 0 else np.zeros((0, 2))
            rect = min_area_rect(np.vstack([obj.boundary_xy(face), unseen]))
            yaw = rect.yaw
        center_xy = rect.center
        size = rect.size
        circle = round_footprint(obj, face, height, noise, rect, whole)
        if circle is not None:  # a round top: its centre even where part of it is out of view
            center_xy, size = circle[0], np.full(2, 2 * circle[1])
        if not flat:  # a tip too sparse to fit: the cap's apex, else the highest points
            height = max(tip, h_hi) if tip is not None else h_hi
    whole_xy, whole_size = whole.center, (float(whole.size.max()), float(whole.size.min()))
    if min(size) < params.min_width:  # a sliver of a top: the object's side is what is seen of it
        side = round_side(b, noise, h_hi)
        if side is not None:
            whole_xy, whole_size = side[0], (2 * side[1], 2 * side[1])
    lw, yaw = length_first(size, yaw)
    centroid = b_all.mean(axis=1, dtype=np.float64)
    return ObjectEstimate(
        center_xy=np.asarray(center_xy, dtype=np.float64), height=height,
        size=lw, yaw=yaw, centroid=centroid, curved=curved, n_points=n,
        whole_xy=np.asarray(whole_xy, dtype=np.float64), whole_size=whole_size,
    )  # fmt: skip
