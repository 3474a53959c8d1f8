"""The board surface measured from the cloud: a robust plane fit, and frame changes.

Frames: ``cfg`` is the configured board frame (``Board.T_base_board``: origin at the configured
board centre on the surface, z up); ``plane`` has its origin on the measured plane above the
configured centre, z along the measured normal and x along the configured board x projected onto
the plane. Heights above the board are z coordinates in ``plane``.

Coordinates are handled as (3, ...) float32 arrays (x, y, z planes): numpy is several times faster
on them than on (..., 3) points, whose innermost axis of length 3 defeats vectorisation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlaneFit:
    """``z = a + b x + c y`` in the configured board frame (metres), from ``n_inliers`` points."""

    coef: tuple[float, float, float]
    rms: float
    n_inliers: int

    @property
    def normal_cfg(self) -> np.ndarray:
        """(3,) unit normal, configured board frame, pointing up."""
        _, b, c = self.coef
        n = np.array([-b, -c, 1.0])
        return n / np.linalg.norm(n)


def coords(points: np.ndarray) -> np.ndarray:
    """(3, ...) float32 copy of points (..., 3) (any dtype, any strides)."""
    with np.errstate(over="ignore"):
        return np.ascontiguousarray(np.moveaxis(np.asarray(points), -1, 0), dtype=np.float32)


def change_frame(c_a: np.ndarray, T_a_f: np.ndarray) -> np.ndarray:
    """Coordinates in frame ``f`` of points given in frame ``a``: ``R^T (c_a - t)``.

    c_a: (3, ...) float32, frame a, metres (NaN and inf pass through). T_a_f: (4, 4) pose of f in
    a. Returns (3, ...) float32.
    """
    R_t = np.ascontiguousarray(T_a_f[:3, :3].T, dtype=np.float32)
    offset = (R_t @ T_a_f[:3, 3].astype(np.float32))[:, None]
    with np.errstate(invalid="ignore", over="ignore"):
        out = R_t @ c_a.reshape(3, -1)
        out -= offset
    return out.reshape(c_a.shape)


def fit_plane(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, thresholds: tuple[float, ...], min_points: int
) -> PlaneFit | None:
    """Robust least-squares plane through board candidate points.

    x, y, z: (n,) float32, configured board frame, metres (finite). Starts from the flat plane at
    the mean height, then refits on the points within each of ``thresholds`` of the previous plane
    (objects and clutter drop out). Returns None when fewer than ``min_points`` remain.
    """
    if z.size < min_points:
        return None
    a, b, c = float(z.mean(dtype=np.float64)), 0.0, 0.0
    n_in = 0
    for thr in thresholds:
        inl = np.abs(z - (a + b * x + c * y)) < thr
        xi, yi, zi = x[inl], y[inl], z[inl]
        n_in = xi.size
        if n_in < min_points:
            return None
        sx, sy = float(xi.sum(dtype=np.float64)), float(yi.sum(dtype=np.float64))
        sxy = float(xi @ yi)
        M = np.array([[float(xi @ xi), sxy, sx], [sxy, float(yi @ yi), sy], [sx, sy, float(n_in)]])
        rhs = np.array([float(xi @ zi), float(yi @ zi), float(zi.sum(dtype=np.float64))])
        b, c, a = (float(v) for v in np.linalg.solve(M, rhs))
    r = z - (a + b * x + c * y)
    r = r[np.abs(r) < thresholds[-1]]
    rms = float(np.sqrt(np.mean(r.astype(np.float64) ** 2))) if r.size else float("nan")
    return PlaneFit((a, b, c), rms, n_in)


def T_cfg_plane(fit: PlaneFit) -> np.ndarray:
    """(4, 4) pose of the measured plane frame in the configured board frame."""
    z_axis = fit.normal_cfg
    x_axis = np.array([1.0, 0.0, 0.0]) - z_axis[0] * z_axis
    x_axis /= np.linalg.norm(x_axis)
    y_axis = np.array(
        [
            z_axis[1] * x_axis[2] - z_axis[2] * x_axis[1],
            z_axis[2] * x_axis[0] - z_axis[0] * x_axis[2],
            z_axis[0] * x_axis[1] - z_axis[1] * x_axis[0],
        ]
    )  # z x x, without np.cross's overhead
    T = np.eye(4)
    T[:3, :3] = np.stack([x_axis, y_axis, z_axis], axis=1)
    T[:3, 3] = (0.0, 0.0, fit.coef[0])
    return T


def planar_transform(x: float, y: float, yaw: float) -> np.ndarray:
    """(4, 4) rotation ``yaw`` about z and translation ``(x, y, 0)``."""
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = ((c, -s), (s, c))
    T[:2, 3] = (x, y)
    return T
