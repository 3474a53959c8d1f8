"""Small SO(3) helpers used by the solver (no scipy overhead on the hot path)."""

from __future__ import annotations

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
    theta = float(np.sqrt(phi @ phi))
    K = hat(phi)
    if theta < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + (np.sin(theta) / theta) * K + ((1.0 - np.cos(theta)) / theta**2) * (K @ K)


def log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of rotation matrices (..., 3, 3), radians."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(R).as_rotvec())


def project(M: np.ndarray) -> np.ndarray:
    """The rotation matrix nearest (Frobenius) to a (3, 3) matrix, via SVD with det = +1."""
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return np.asarray(U @ np.diag([1.0, 1.0, d]) @ Vt)
