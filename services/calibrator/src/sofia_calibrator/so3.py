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


def log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of rotation matrices (..., 3, 3), radians."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(R).as_rotvec())


def project(M: np.ndarray) -> np.ndarray:
    """The rotation matrix nearest (Frobenius) to a (3, 3) matrix, via SVD with det = +1."""
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, 2] = -U[:, 2]
        R = U @ Vt
    return np.asarray(R)
