"""Rectangles around 2-D point sets: the convex hull and the rectangle of least area (OpenCV)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

QUARTER = math.pi / 2


@dataclass(frozen=True)
class Rect:
    """Rectangle: ``yaw`` of its first axis; ``lo``, ``hi`` (2,) bounds along its two axes. Derived,
    read-only (shared by whoever reads them): ``R`` (2, 2) rotation whose columns are its axes,
    ``center`` (2,) in the frame of the points, ``size`` (2,) extent along its axes."""

    yaw: float
    lo: np.ndarray
    hi: np.ndarray
    R: np.ndarray = field(init=False)
    center: np.ndarray = field(init=False)
    size: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        R = np.array([[c, -s], [s, c]])
        for name, value in (("R", R), ("center", R @ ((self.lo + self.hi) / 2)), ("size", self.hi - self.lo)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)


def hull(xy: np.ndarray) -> np.ndarray:
    """(k, 2) float64 convex hull vertices of ``xy`` (n, 2) (OpenCV's; the points themselves when
    fewer than 3)."""
    xy = np.asarray(xy, dtype=np.float64)
    if xy.shape[0] < 3:
        return xy
    at = cv2.convexHull((xy - xy[0]).astype(np.float32), returnPoints=False)
    return xy[at[:, 0]]


def min_area_rect(xy: np.ndarray, max_yaw: float | None = None) -> Rect:
    """Minimum-area rectangle of xy (k, 2), k >= 1, yaw in ``[-pi/4, pi/4)``: OpenCV's, or when
    its yaw is beyond ``max_yaw``, the least over the hull edges within it (yaw 0 when none is)."""
    xy = np.asarray(xy, dtype=np.float64)
    (cx, cy), size, angle = cv2.minAreaRect((xy - xy[0]).astype(np.float32))  # float32: 0.1 um here
    turned = math.radians(angle)
    yaw = (turned + QUARTER / 2) % QUARTER - QUARTER / 2
    if max_yaw is None or abs(yaw) <= max_yaw:  # the least of all is the least of those allowed
        if round((turned - yaw) / QUARTER) % 2:
            size = size[::-1]
        c, s = math.cos(yaw), math.sin(yaw)
        x0, y0 = cx + xy[0, 0], cy + xy[0, 1]
        mid = np.array([c * x0 + s * y0, -s * x0 + c * y0])
        return Rect(yaw, mid - np.array(size) / 2, mid + np.array(size) / 2)
    v = hull(xy)
    edge = np.roll(v, -1, axis=0) - v
    yaws = (np.arctan2(edge[:, 1], edge[:, 0]) + QUARTER / 2) % QUARTER - QUARTER / 2
    yaws = yaws[np.abs(yaws) <= max_yaw]
    if yaws.size == 0:
        yaws = np.zeros(1)
    c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
    u, w = c * v[:, 0] + s * v[:, 1], c * v[:, 1] - s * v[:, 0]  # (yaws, k) along the two axes
    lo, hi = np.stack([u.min(axis=1), w.min(axis=1)], 1), np.stack([u.max(axis=1), w.max(axis=1)], 1)
    i = int(np.argmin(np.prod(hi - lo, axis=1)))
    return Rect(float(yaws[i]), lo[i], hi[i])
