"""The board surface measured from the cloud: a robust plane fit, and frame changes.

Frames: ``cfg`` is the configured board frame (``Board.T_base_board``: origin at the configured
board centre on the surface, z up); ``plane`` has its origin on the measured plane above the
configured centre, z along the measured normal and x along the configured board x projected onto
the plane. Heights above the board are z coordinates in ``plane``.

Coordinates are handled as (3, ...) float32 arrays (x, y, z planes): numpy is several times faster
on them than on (..., 3) points, whose innermost axis of length 3 defeats vectorisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .kernels import jit


@dataclass(frozen=True)
class PlaneFit:
    """``z = a + b x + c y`` in the configured board frame (metres), from ``n_inliers`` points."""

    coef: tuple[float, float, float]
    rms: float
    n_inliers: int

    @property
    def normal_cfg(self) -> tuple[float, float, float]:
        """Unit normal (x, y, z), configured board frame, pointing up."""
        _, b, c = self.coef
        n = math.sqrt(b * b + c * c + 1.0)
        return -b / n, -c / n, 1.0 / n


def coords(points: np.ndarray) -> np.ndarray:
    """(3, ...) float32 copy of points (..., 3) (any dtype, any strides)."""
    with np.errstate(over="ignore"):
        return np.ascontiguousarray(np.moveaxis(np.asarray(points), -1, 0), dtype=np.float32)


@jit
def _in_frame(
    R_t: np.ndarray, offset: np.ndarray, x: np.float32, y: np.float32, z: np.float32, i: int
) -> np.float32:
    """Coordinate ``i`` in frame f of the point (x, y, z) of frame a: ``(R^T p - R^T t)[i]``, float32
    (:func:`_rotation_offset`)."""
    return (R_t[i, 0] * x + R_t[i, 1] * y + R_t[i, 2] * z) - offset[i]  # type: ignore[no-any-return]


@jit
def _change_frame(c_a: np.ndarray, R_t: np.ndarray, offset: np.ndarray) -> np.ndarray:
    out = np.empty_like(c_a)
    for k in range(c_a.shape[1]):
        x, y, z = c_a[0, k], c_a[1, k], c_a[2, k]
        for i in range(3):
            out[i, k] = _in_frame(R_t, offset, x, y, z, i)
    return out


@jit
def _points_in_frame(p_a: np.ndarray, R_t: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """:func:`_change_frame` of (h, w, 3) points of any strides, each cast to float32 first."""
    h, w, _ = p_a.shape
    out = np.empty((3, h, w), dtype=np.float32)
    for r in range(h):
        for c in range(w):
            x, y, z = np.float32(p_a[r, c, 0]), np.float32(p_a[r, c, 1]), np.float32(p_a[r, c, 2])
            for i in range(3):
                out[i, r, c] = _in_frame(R_t, offset, x, y, z, i)
    return out


def _rotation_offset(T_a_f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3, 3) float32 ``R^T`` and (3,) float32 ``R^T t`` of a pose (4, 4): ``c_f = R^T c_a - R^T t``."""
    R_t = np.ascontiguousarray(T_a_f[:3, :3].T, dtype=np.float32)
    return R_t, R_t @ T_a_f[:3, 3].astype(np.float32)


def change_frame(c_a: np.ndarray, T_a_f: np.ndarray) -> np.ndarray:
    """Coordinates in frame ``f`` of points given in frame ``a``: ``R^T (c_a - t)``.

    c_a: (3, ...) float32, frame a, metres (NaN and inf pass through). T_a_f: (4, 4) pose of f in
    a. Returns (3, ...) float32. Compiled, in one thread: a BLAS product would be split over the
    cores for large clouds, and OpenBLAS's threads spin on after it, taking the other core.
    """
    R_t, offset = _rotation_offset(T_a_f)
    flat = np.ascontiguousarray(c_a, dtype=np.float32).reshape(3, -1)
    return _change_frame(flat, R_t, offset).reshape(c_a.shape)  # type: ignore[no-any-return]


def points_in_frame(points_a: np.ndarray, T_a_f: np.ndarray) -> np.ndarray:
    """``change_frame(coords(points_a), T_a_f)`` in one pass, without the copy: (3, ...) float32
    coordinates in frame ``f`` of points_a (..., 3) given in frame ``a`` (float32 or float64, any
    strides: a view of received bytes, every stride-th pixel of a cloud)."""
    p = np.asarray(points_a)
    if p.dtype not in (np.float32, np.float64) or p.ndim not in (2, 3):
        return change_frame(coords(p), T_a_f)
    R_t, offset = _rotation_offset(T_a_f)
    out = _points_in_frame(p if p.ndim == 3 else p[None], R_t, offset)
    return out if p.ndim == 3 else out[:, 0]  # type: ignore[no-any-return]


@jit
def _refits(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, thresholds: np.ndarray, min_points: int
) -> tuple[float, float, float, float, int]:
    """(a, b, c, rms, n_inliers) of :func:`fit_plane`; n_inliers < ``min_points`` when it fails."""
    a, b, c = z.astype(np.float64).mean(), 0.0, 0.0
    n_in = 0
    for thr in thresholds:
        M = np.zeros((3, 3))
        rhs = np.zeros(3)
        n_in = 0
        for i in range(z.size):
            xi, yi, zi = np.float64(x[i]), np.float64(y[i]), np.float64(z[i])
            if abs(zi - (a + b * xi + c * yi)) < thr:
                n_in += 1
                M[0, 0] += xi * xi
                M[0, 1] += xi * yi
                M[0, 2] += xi
                M[1, 1] += yi * yi
                M[1, 2] += yi
                rhs[0] += xi * zi
                rhs[1] += yi * zi
                rhs[2] += zi
        if n_in < min_points:
            return a, b, c, np.nan, n_in
        M[1, 0], M[2, 0], M[2, 1], M[2, 2] = M[0, 1], M[0, 2], M[1, 2], n_in
        if np.linalg.det(M) == 0.0:  # the inliers lie on a line: no plane
            return a, b, c, np.nan, -1
        b, c, a = np.linalg.solve(M, rhs)
    sq, k = 0.0, 0
    for i in range(z.size):
        r = np.float64(z[i]) - (a + b * np.float64(x[i]) + c * np.float64(y[i]))
        if abs(r) < thresholds[-1]:
            sq += r * r
            k += 1
    return a, b, c, np.sqrt(sq / k) if k else np.nan, n_in


def fit_plane(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, thresholds: tuple[float, ...], min_points: int
) -> PlaneFit | None:
    """Robust least-squares plane through board candidate points.

    x, y, z: (n,) float32, configured board frame, metres (finite). Starts from the flat plane at
    the mean height, then refits on the points within each of ``thresholds`` of the previous plane
    (objects and clutter drop out). Returns None when fewer than ``min_points`` remain or they lie
    on a line.
    """
    if z.size < min_points:
        return None
    x, y, z = (np.ascontiguousarray(v, dtype=np.float32) for v in (x, y, z))
    a, b, c, rms, n_in = _refits(x, y, z, np.asarray(thresholds, dtype=np.float64), min_points)
    if n_in < min_points:
        return None
    return PlaneFit((float(a), float(b), float(c)), float(rms), int(n_in))


def T_cfg_plane(fit: PlaneFit) -> np.ndarray:
    """(4, 4) pose of the measured plane frame in the configured board frame: z along the
    normal, x along the configured x projected onto the plane (scalar arithmetic: numpy's
    per-call overhead would dominate on 3-vectors)."""
    zx, zy, zz = fit.normal_cfg
    xx, xy, xz = 1.0 - zx * zx, -zx * zy, -zx * zz  # (1, 0, 0) without its normal component
    k = math.sqrt(xx * xx + xy * xy + xz * xz)
    xx, xy, xz = xx / k, xy / k, xz / k
    yx, yy, yz = zy * xz - zz * xy, zz * xx - zx * xz, zx * xy - zy * xx  # z x x
    return np.array([[xx, yx, zx, 0.0], [xy, yy, zy, 0.0], [xz, yz, zz, fit.coef[0]], [0.0, 0.0, 0.0, 1.0]])


def planar_transform(x: float, y: float, yaw: float) -> np.ndarray:
    """(4, 4) rotation ``yaw`` about z and translation ``(x, y, 0)``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
