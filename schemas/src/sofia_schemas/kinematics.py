"""Franka Emika Panda / FR3 forward kinematics from Franka's modified (Craig) DH parameters.

Each link: T_{i-1}_{i} = RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i) TransZ(d_i). The flange
(``panda_link8``) is 0.107 m along joint 7's z axis. The Panda and the FR3 share these parameters;
their joint limits differ. The arm service and the calibrator use this one implementation.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from .errors import SofiaError

# (a, d, alpha) per joint, metres and radians (frankaemika.github.io/docs/control_parameters.html)
PANDA_DH = np.array([
    [0.0, 0.333, 0.0],
    [0.0, 0.0, -np.pi / 2],
    [0.0, 0.316, np.pi / 2],
    [0.0825, 0.0, np.pi / 2],
    [-0.0825, 0.384, -np.pi / 2],
    [0.0, 0.0, np.pi / 2],
    [0.088, 0.0, np.pi / 2],
    [0.0, 0.107, 0.0],  # flange, fixed
])  # fmt: skip
# Joint limits (rad) from the same page.
Q_MIN = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
Q_MAX = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
FR3_Q_MIN = np.array([-2.7437, -1.7837, -2.9007, -3.0421, -2.8065, 0.5445, -3.0159])
FR3_Q_MAX = np.array([2.7437, 1.7837, 2.9007, -0.1518, 2.8065, 4.5169, 3.0159])
RobotModel = Literal["panda", "fr3"]


class KinematicsError(SofiaError, ValueError):
    """Joint positions that cannot be used: wrong shape, not finite, outside the limits."""


def joint_limits(model: RobotModel = "panda") -> tuple[np.ndarray, np.ndarray]:
    """(q_min (7,), q_max (7,)) radians of the ``panda`` or the ``fr3``."""
    return (Q_MIN, Q_MAX) if model == "panda" else (FR3_Q_MIN, FR3_Q_MAX)


def _mdh(a: float, d: float, alpha: float, theta: np.ndarray) -> np.ndarray:
    """(n, 4, 4) modified-DH link transforms for joint angles theta (n,)."""
    n = len(theta)
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    T = np.zeros((n, 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 0, 3] = ct, -st, a
    T[:, 1, 0], T[:, 1, 1], T[:, 1, 2], T[:, 1, 3] = st * ca, ct * ca, -sa, -sa * d
    T[:, 2, 0], T[:, 2, 1], T[:, 2, 2], T[:, 2, 3] = st * sa, ct * sa, ca, ca * d
    T[:, 3, 3] = 1.0
    return T


def panda_fk(q: np.ndarray, check_limits: bool = True) -> np.ndarray:
    """T_base_flange (n, 4, 4) of joint positions q (n, 7) or (7,) radians (base = panda_link0).

    Raises KinematicsError for a wrong shape, non-finite values or (``check_limits``) a joint
    outside the Panda's limits.
    """
    q = np.asarray(q, dtype=np.float64)
    single = q.ndim == 1
    q = np.atleast_2d(q)
    if q.ndim != 2 or q.shape[1] != 7:
        raise KinematicsError(f"Panda joint positions must have shape (n, 7) or (7,), got {q.shape}")
    if not np.all(np.isfinite(q)):
        rows = np.flatnonzero(~np.isfinite(q).all(1)).tolist()
        raise KinematicsError(f"joint positions have non-finite values in rows {rows}")
    if check_limits:
        bad = np.argwhere((q < Q_MIN - 1e-6) | (q > Q_MAX + 1e-6))
        if bad.size:
            i, j = bad[0]
            raise KinematicsError(
                f"joint {j + 1} of sample {i} is {q[i, j]:.4f} rad, outside the Panda's limits "
                f"[{Q_MIN[j]}, {Q_MAX[j]}] (values must be radians)"
            )
    T = np.tile(np.eye(4), (len(q), 1, 1))
    thetas = np.concatenate([q, np.zeros((len(q), 1))], axis=1)
    for k, (a, d, alpha) in enumerate(PANDA_DH):
        T = T @ _mdh(a, d, alpha, thetas[:, k])
    return T[0] if single else T
