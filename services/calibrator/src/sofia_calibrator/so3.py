"""Small SO(3) helpers used by the solver (no scipy overhead on the hot path)."""

from __future__ import annotations

import math

import numpy as np


def hat(v: np.ndarray) -> np.ndarray:
    """Skew matrices [v]x of (..., 3) vectors: (..., 3, 3), ``hat(v) @ w == cross(v, w)``."""
    v = np.asarray(v, dtype=np.float64)
    S = np.zeros((*v.shape[:-1], 3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def exp(phi: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of the rotation vector phi (3,) (axis times angle, radians)."""
    x, y, z = float(phi[0]), float(phi[1]), float(phi[2])
    theta2 = x * x + y * y + z * z
    if theta2 < 1e-16:
        a, b = 1.0, 0.5
    else:
        theta = math.sqrt(theta2)
        a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta2
    # R = I + a K + b K^2 with K = [phi]x, written out
    return np.array([
        [1.0 - b * (y * y + z * z), -a * z + b * x * y, a * y + b * x * z],
        [a * z + b * x * y, 1.0 - b * (x * x + z * z), -a * x + b * y * z],
        [-a * y + b * x * z, a * x + b * y * z, 1.0 - b * (x * x + y * y)],
    ])  # fmt: skip


_LOG_I, _LOG_J = [2, 0, 1], [1, 2, 0]  # R[i, j] - R[j, i]: the skew part of R as a vector


def log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of rotation matrices (..., 3, 3), radians.

    From the skew part and the trace; rotations within 1e-3 rad of pi go through scipy (the skew
    part vanishes there)."""
    R = np.asarray(R, dtype=np.float64)
    w = R[..., _LOG_I, _LOG_J] - R[..., _LOG_J, _LOG_I]  # 2 sin(theta) times the axis
    cos = np.minimum(np.maximum((R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0) * 0.5, -1.0), 1.0)
    sin = 0.5 * np.sqrt(np.einsum("...i,...i->...", w, w))
    theta = np.arctan2(sin, cos)
    f = np.where(sin > 1e-12, theta / np.maximum(2.0 * sin, 1e-300), 0.5 + theta**2 / 12.0)
    out = w * f[..., None]
    near_pi = theta > np.pi - 1e-3
    if near_pi.any():
        from scipy.spatial.transform import Rotation

        out[near_pi] = Rotation.from_matrix(R[near_pi]).as_rotvec()
    return np.asarray(out)


def project(M: np.ndarray) -> np.ndarray:
    """The rotation matrix nearest (Frobenius) to a (3, 3) matrix, via SVD with det = +1."""
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, 2] = -U[:, 2]
        R = U @ Vt
    return np.asarray(R)
