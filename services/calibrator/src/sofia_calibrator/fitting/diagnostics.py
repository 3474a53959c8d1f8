"""What a calibration says about itself: mapped blob, spread, dissipation, uncertainty, outliers,
observability. Inputs are trusted (validated by :func:`sofia_calibrator.calibrate`)."""

from __future__ import annotations

import math

import numpy as np
from sofia_schemas.transforms import apply

from ..errors import DegenerateMotion
from . import kernels, so3
from .kernels import jit
from .so3 import log_so3

LAB_SPREAD_LIMIT_MM = 10.0
MIN_ROTATION_DEG = 2.0
WEAK_ROTATION_DEG = 10.0
ONE_AXIS_RATIO = 0.3  # second rotation spread below this fraction of the first: one axis
# Family-wise probability of calling a sample of a clean set a clear outlier.
OUTLIER_ALPHA = 0.001
DENSE_PAIRS_MAX = 256  # dissipation: pairwise distances as one (n, n) matrix up to this n


def map_to_base(T_base_flange: np.ndarray, T_flange_cam: np.ndarray, p_cam: np.ndarray) -> np.ndarray:
    """Blob positions mapped into the base frame: T_base_flange_i T_flange_cam p_cam_i.

    T_base_flange: (n, 4, 4); T_flange_cam: (4, 4); p_cam: (n, 3) camera frame, metres.
    Returns p_base (n, 3), metres.
    """
    return apply(T_base_flange, apply(T_flange_cam, p_cam))


def fmt3(v: np.ndarray, digits: int = 1) -> str:
    """A (3,) vector as "[a, b, c]" rounded to ``digits``."""
    return "[" + ", ".join(f"{float(x):.{digits}f}" for x in v) + "]"


def spread(p_base: np.ndarray) -> np.ndarray:
    """Per-axis max - min of (n, 3) points (the lab's criterion): (3,), same unit as the points."""
    return np.asarray(p_base.max(axis=0) - p_base.min(axis=0))


def dissipation(p_base: np.ndarray) -> float:
    """The lab's objective: sum over ordered pairs i != j of ||p_i - p_j||, metres.

    p_base: (n, 3) points. Up to ``DENSE_PAIRS_MAX`` points the (n, n) distance matrix at once
    (fewest calls); above, scipy's pdist (n (n - 1) / 2 distances, no (n, n, 3) temporary)."""
    if len(p_base) <= DENSE_PAIRS_MAX:
        d = p_base[:, None, :] - p_base[None, :, :]
        return float(np.sqrt(np.einsum("ijk,ijk->ij", d, d)).sum())
    from scipy.spatial.distance import pdist

    return float(2.0 * pdist(p_base).sum())


def std_from_covariance6(cov6: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1-sigma of (translation mm, rotation deg about the flange axes) from the (6, 6) covariance
    of :func:`covariance6`."""
    std = np.sqrt(np.maximum(cov6.diagonal(), 0.0))
    return 1e3 * std[:3], np.degrees(std[3:])


def covariance6(R_flange_cam: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(6, 6) covariance of T_flange_cam: (tx, ty, tz) metres, then (rx, ry, rz) radians about the
    flange axes (left perturbation), from the solver's covariance of (theta_cam, t, ...)."""
    A = np.zeros((6, cov.shape[0]))
    A[:3, 3:6] = np.eye(3)
    A[3:, :3] = R_flange_cam  # phi_flange = R theta_cam
    return np.asarray(A @ cov @ A.T)


def error6(T_est: np.ndarray, T_true: np.ndarray) -> np.ndarray:
    """(6,) error of an estimated T_flange_cam (4, 4) against the true one, in the coordinates of
    :func:`covariance6`: translation (m, flange frame), then rotation (rad, about the flange axes)."""
    return np.r_[T_est[:3, 3] - T_true[:3, 3], so3.log(T_est[:3, :3] @ T_true[:3, :3].T)]


def check_motion(T_base_flange: np.ndarray) -> list[str]:
    """Observability of the flange motion; raises DegenerateMotion, or returns warnings.

    T_base_flange: (n, 4, 4). The rotation vectors of R_0^T R_i must span more than one axis:
    with translation only, the camera offset is not observable; with rotations about one axis
    only, the offset along that axis is not.
    """
    s, S = rotation_spread(kernels.c_array(T_base_flange[:, :3, :3]))
    if s[0] < MIN_ROTATION_DEG:
        raise DegenerateMotion(
            f"the flange barely rotates between samples (largest rotation spread {s[0]:.2f} deg)",
            "translation-only motion cannot locate the camera; tilt the flange by 15-30 deg about "
            "two different axes while keeping the blob in view",
        )
    if s[1] < MIN_ROTATION_DEG and s[1] < ONE_AXIS_RATIO * s[0]:
        axis = np.linalg.eigh(S)[1][:, 2]
        raise DegenerateMotion(
            f"all rotations are about one axis (flange axis {np.round(axis, 2).tolist()}, "
            f"spread about other axes {s[1]:.2f} deg)",
            "the camera offset along that axis is not observable; add poses tilted about another axis",
        )
    if s[1] < MIN_ROTATION_DEG:
        raise DegenerateMotion(
            f"the rotations are small about every axis (spread {fmt3(s, 2)} deg)",
            "the camera offset is barely observable; tilt the flange by 15-30 deg about two different axes",
        )
    if s[1] < WEAK_ROTATION_DEG:
        return [
            f"rotations are nearly about one axis (spread about the second axis {s[1]:.1f} deg): "
            "add poses tilted about a different axis to pin the camera offset"
        ]
    return []


@jit
def rotation_spread(R_base_flange):  # type: ignore[no-untyped-def]
    """How the flange turns over a set (see :func:`check_motion`):
    rel (n - 1, 3) the rotation vectors of R_0^T R_i; returns (s (3,) the RMS spread of rel along
    its principal axes, degrees, largest first; rel^T rel (3, 3))."""
    n = R_base_flange.shape[0]
    rel_R = np.empty((max(n - 1, 0), 3, 3))
    R_0_base = R_base_flange[0].T.copy()
    for i in range(1, n):
        rel_R[i - 1] = R_0_base @ R_base_flange[i]
    rel = log_so3(rel_R)
    S = rel.T @ rel
    ev = np.linalg.eigvalsh(S)[::-1]  # singular values of rel, squared, largest first
    return np.degrees(np.sqrt(np.maximum(ev, 0.0))) / math.sqrt(max(n - 1, 1)), S
