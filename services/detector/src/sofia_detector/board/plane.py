"""The board plane: a robust least-squares fit, and the frames it defines."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlaneFit:
    """``z = a + b x + c y`` in the configured board frame (metres), from ``n_inliers`` points."""

    coef: tuple[float, float, float]
    rms: float
    n_inliers: int


def fit_plane(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, thresholds: tuple[float, ...], min_points: int
) -> PlaneFit | None:
    """Robust plane through x, y, z (n,) float (configured board frame, metres, finite): from the
    flat plane at the mean height, refitted on the points within each of ``thresholds`` of the
    previous one; None when fewer than ``min_points`` remain or they lie on a line."""
    if z.size < min_points:
        return None
    A = np.stack([x, y, np.ones(z.size)]).astype(np.float64)  # (3, n)
    z = z.astype(np.float64)
    coef, n_in = np.array([0.0, 0.0, z.mean()]), 0  # b, c, a
    for thr in thresholds:
        inl = np.abs(z - coef @ A) < thr
        n_in = int(np.count_nonzero(inl))
        B = np.compress(inl, A, axis=1)
        M = B @ B.T
        if n_in < min_points or np.linalg.det(M) == 0.0:  # too few, or on a line: no plane
            return None
        coef = np.linalg.solve(M, B @ z[inl])
    r = z - coef @ A
    r = r[np.abs(r) < thresholds[-1]]
    rms = float(np.sqrt(np.mean(r * r))) if r.size else math.nan
    return PlaneFit((float(coef[2]), float(coef[0]), float(coef[1])), rms, n_in)


def T_cfg_plane(fit: PlaneFit) -> np.ndarray:
    """(4, 4) pose of the plane frame in the configured board frame: z along the normal, x along
    the configured x projected onto the plane (scalars: numpy's overhead dominates on 3-vectors)."""
    _, b, c = fit.coef
    n = math.sqrt(b * b + c * c + 1.0)
    zx, zy, zz = -b / n, -c / n, 1.0 / n  # the unit normal, pointing up
    xx, xy, xz = 1.0 - zx * zx, -zx * zy, -zx * zz  # (1, 0, 0) without its normal component
    k = math.sqrt(xx * xx + xy * xy + xz * xz)
    xx, xy, xz = xx / k, xy / k, xz / k
    yx, yy, yz = zy * xz - zz * xy, zz * xx - zx * xz, zx * xy - zy * xx  # z x x
    return np.array([[xx, yx, zx, 0.0], [xy, yy, zy, 0.0], [xz, yz, zz, fit.coef[0]], [0.0, 0.0, 0.0, 1.0]])


def planar_transform(x: float, y: float, yaw: float) -> np.ndarray:
    """(4, 4) rotation ``yaw`` about z and translation ``(x, y, 0)``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
