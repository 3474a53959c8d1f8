"""A coloured ball in an organized RGB-D frame: its pixels by colour, its centre by a sphere fit.

The ball's pixels: the largest connected region of strongly coloured pixels (OpenCV HSV,
``connectedComponentsWithStats``) eroded by a pixel (the depth edge's mixed pixels out); their
points go to :mod:`~sofia_calibrator.targets.sphere` with an inlier band matched to the D435's
depth noise at the ball's distance. The centre serves wherever a blob's does (either set-up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputMismatch
from .sphere import DEFAULT_INLIER_M, Sphere, SphereNotFound, refine_sphere, segment_sphere

MIN_SATURATION = 110  # OpenCV HSV saturation (0-255) above which a pixel may be the ball's
MIN_VALUE = 50  # and brightness above which (dark pixels have unreliable hue)
MIN_PIXELS = 40
CLOUD_TARGETS = ("blob", "ball")  # the targets found in an organized RGB-D cloud
NOISE_AT_HALF_M = 0.001  # the D435's depth 1-sigma at 0.5 m, growing with the square of the depth


@dataclass
class Ball:
    """A ball found in a frame: the sphere fit (camera optical frame, metres) and where it was seen."""

    sphere: Sphere
    confidence: float  # 0..1: the share of the ball's pixels on the fitted sphere
    centroid_px: tuple[float, float]  # (u, v) of the ball's pixels
    # (inliers (k, 3) camera frame m, RANSAC centre (3,), radius): the view's segment, for one
    # radius fitted to several views (:func:`~sofia_calibrator.targets.sphere_shared.fit_shared`)
    segment: tuple[np.ndarray, np.ndarray, float]

    @property
    def p_cam(self) -> np.ndarray:
        """(3,) the centre, camera optical frame, metres."""
        return self.sphere.p_cam


def ball_mask(rgb: np.ndarray) -> np.ndarray:
    """(H, W) bool: the largest connected region of strongly coloured pixels of rgb (H, W, 3)
    uint8, eroded by one pixel. Raises SphereNotFound when there is none of ``MIN_PIXELS``."""
    import cv2

    hsv = cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2HSV)
    coloured = ((hsv[..., 1] >= MIN_SATURATION) & (hsv[..., 2] >= MIN_VALUE)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(coloured, connectivity=8)
    if n < 2:
        raise SphereNotFound("no coloured pixels in the image")
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[best, cv2.CC_STAT_AREA] < MIN_PIXELS:
        raise SphereNotFound(
            f"the largest coloured region has {stats[best, cv2.CC_STAT_AREA]} pixels (need {MIN_PIXELS})"
        )
    region = (labels == best).astype(np.uint8)
    return np.asarray(cv2.erode(region, np.ones((3, 3), np.uint8)) > 0)


def find_ball(points_cam: np.ndarray, rgb: np.ndarray, radius_m: float | None = None) -> Ball:
    """The ball in an organized frame. points_cam: (H, W, 3) float, camera optical frame, metres,
    NaN where missing; rgb: (H, W, 3) uint8; radius_m: the known radius (metres) or None to fit it.
    Raises :class:`SphereNotFound` (no coloured region, too few points with depth, no sphere)."""
    p = np.asarray(points_cam, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3 or np.shape(rgb) != p.shape:
        raise InputMismatch(
            f"need an organized cloud (H, W, 3) and rgb of its shape, got {p.shape}, {np.shape(rgb)}"
        )
    mask = ball_mask(rgb)
    pts = p[mask]
    pts = pts[np.isfinite(pts).all(axis=1) & (pts[:, 2] > 0)]
    if len(pts) < MIN_PIXELS:
        raise SphereNotFound(
            f"{len(pts)} of the ball's {int(mask.sum())} pixels have depth (need {MIN_PIXELS})"
        )
    z = float(np.median(pts[:, 2]))
    inlier_m = max(DEFAULT_INLIER_M, 2.5 * NOISE_AT_HALF_M * (z / 0.5) ** 2)
    segment = segment_sphere(pts, radius_m, inlier_m)
    inliers, centre, radius = segment
    sphere = refine_sphere(inliers, centre, radius if radius_m is None else radius_m, radius_m is None)
    v, u = np.nonzero(mask)
    return Ball(sphere, min(1.0, sphere.n_inliers / len(pts)), (float(u.mean()), float(v.mean())), segment)


def find_target(
    kind: str, points_cam: np.ndarray, rgb: np.ndarray, radius_m: float | None = None
) -> tuple[np.ndarray, float, tuple[np.ndarray, np.ndarray, float] | None]:
    """(p_cam (3,) camera optical frame m, confidence 0..1, the ball's segment or None for a blob)
    of a ``kind`` (``CLOUD_TARGETS``) target in an organized cloud (:func:`find_ball`'s arguments)."""
    if kind == "ball":
        ball = find_ball(points_cam, rgb, radius_m)
        return ball.p_cam, ball.confidence, ball.segment
    from ..blob import find_blob

    blob = find_blob(points_cam, rgb)
    return blob.p_cam, blob.confidence, None
