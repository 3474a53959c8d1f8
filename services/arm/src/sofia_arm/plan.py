"""Which calibration pose to visit next: the information each candidate view adds to the
calibrator's model, and the camera's rotation on the flange from the table seen in two views.

The model is the calibrator's (``sofia_calibrator.fitting.solver``): a sample i says
``R_bf_i (R_fc p_cam_i + t_fc) + t_bf_i = p_base`` with camera-frame noise ``camera_sigma(p_cam_i)``.
Parameters (9,): rotation perturbation theta (right, camera frame), t_fc (flange frame, m), p_base
(base frame, m), the order of the calibrator's covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sofia_calibrator.fitting.noise import camera_sigma
from sofia_calibrator.fitting.so3 import hat, project
from sofia_schemas.transforms import apply, invert

# A weak prior keeps the information matrix invertible before there are enough samples:
# 1 rad on the rotation, 0.3 m on the camera offset, 0.3 m on the blob position.
PRIOR_SIGMA = np.array([1.0, 1.0, 1.0, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3])
ROTATION_LEVER_M = 0.1  # a rotation error matters as a translation error at this distance


def information(T_base_flange: np.ndarray, T_flange_cam: np.ndarray, p_base: np.ndarray) -> np.ndarray:
    """(n, 9, 9) Fisher information of samples taken at flange poses (n, 4, 4) of a blob at
    ``p_base`` (3,) seen by a camera at ``T_flange_cam`` (4, 4), under the D435 noise model."""
    T_bf = np.asarray(T_base_flange, dtype=np.float64).reshape(-1, 4, 4)
    T_bc = T_bf @ T_flange_cam
    p_cam = apply(invert(T_bc), np.broadcast_to(p_base, (len(T_bc), 3)))
    R_bc = T_bc[:, :3, :3]
    J = np.concatenate([-R_bc @ hat(p_cam), T_bf[:, :3, :3], np.broadcast_to(-np.eye(3), R_bc.shape)], axis=2)
    W = np.einsum("nij,nj,nkj->nik", R_bc, 1.0 / camera_sigma(p_cam) ** 2, R_bc)  # base frame
    return np.asarray(np.einsum("nji,njk,nkl->nil", J, W, J))


def prior_information() -> np.ndarray:
    """(9, 9) information of the weak prior."""
    return np.diag(1.0 / PRIOR_SIGMA**2)


def covariance_score(info: np.ndarray) -> np.ndarray:
    """(...,) what the planner minimises for information matrices (..., 9, 9): the variance of the
    camera offset (trace, m^2) plus that of the rotation at a lever of ``ROTATION_LEVER_M``."""
    cov = np.linalg.inv(info)
    return np.asarray(
        np.trace(cov[..., 3:6, 3:6], axis1=-2, axis2=-1)
        + ROTATION_LEVER_M**2 * np.trace(cov[..., :3, :3], axis1=-2, axis2=-1)
    )


def translation_sigma_mm(info: np.ndarray) -> np.ndarray:
    """(3,) predicted 1-sigma of t_fc (flange axes, mm) of a (9, 9) information matrix."""
    return np.asarray(1e3 * np.sqrt(np.diag(np.linalg.inv(info))[3:6]))


@dataclass
class Ranked:
    order: np.ndarray  # (m,) candidate indices, best first
    scores: np.ndarray  # (m,) score after adding each candidate, same order


def rank_candidates(
    info_so_far: np.ndarray,
    T_base_flange_candidates: np.ndarray,
    T_flange_cam: np.ndarray,
    p_base: np.ndarray,
) -> Ranked:
    """Candidates (m, 4, 4) ranked by the covariance left after adding each one to ``info_so_far``
    (9, 9): the greedy choice that shrinks the calibrator's covariance most is ``order[0]``."""
    info_c = information(T_base_flange_candidates, T_flange_cam, p_base)
    scores = covariance_score(info_so_far[None] + info_c)
    order = np.argsort(scores)
    return Ranked(order, scores[order])


def wahba(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) rotation R minimising sum ||a_i - R b_i||^2 for unit vectors a, b (n, 3), n >= 2
    not all parallel (SVD solution of Wahba's problem)."""
    return project(np.einsum("ni,nj->ij", a, b))


def table_plane_cam(points_cam: np.ndarray, min_points: int = 500) -> tuple[np.ndarray, float] | None:
    """The dominant plane of a camera-frame cloud (..., 3) (NaN allowed): its unit normal (3,),
    pointing towards the camera, and the camera's distance to it (m); None when fewer than
    ``min_points`` valid points lie on it.

    A least-squares plane of all points is refitted to the points within 1 cm of it, so a few
    off-plane objects do not tilt it.
    """
    p = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    p = p[:: max(1, len(p) // 20000)]
    if len(p) < min_points:
        return None
    c = p.mean(axis=0)
    n = np.linalg.svd(p - c, full_matrices=False)[2][2]
    near = p[np.abs((p - c) @ n) < 0.01]
    if len(near) < min_points:
        return None
    c = near.mean(axis=0)
    n = np.linalg.svd(near - c, full_matrices=False)[2][2]
    n = n if n @ c < 0 else -n
    return n, float(-(n @ c))


def rotation_from_table(T_base_flange: np.ndarray, normals_cam: np.ndarray) -> np.ndarray:
    """(3, 3) R_flange_cam from the table's up direction seen in >= 2 views.

    T_base_flange: (n, 4, 4) flange poses of the views; normals_cam: (n, 3) the table normal in each
    camera frame (pointing up, i.e. towards the camera). The base z axis in the flange frame,
    ``R_bf^T e_z``, equals ``R_fc n_cam``; flange tilts about two different axes fix R_fc.
    """
    up_flange = np.asarray(T_base_flange)[:, 2, :3]  # rows: R_bf^T e_z
    return wahba(up_flange, np.asarray(normals_cam))


def offset_given_rotation(
    T_base_flange: np.ndarray, R_flange_cam: np.ndarray, p_cam: np.ndarray, min_singular: float = 0.05
) -> tuple[np.ndarray, np.ndarray] | None:
    """(t_flange_cam (3,), p_base (3,)) by linear least squares when the camera's rotation is known
    (from the table): ``R_bf_i t - p_base = -(R_bf_i R_fc p_cam_i + t_bf_i)`` for samples at flange
    poses (n, 4, 4) seeing the blob at p_cam (n, 3). None while the flange rotations leave it
    ill-conditioned (smallest singular value of the normalised system below ``min_singular``).
    """
    T = np.asarray(T_base_flange, dtype=np.float64)
    R_bf, n = T[:, :3, :3], len(T)
    A = np.concatenate([R_bf, np.broadcast_to(-np.eye(3), (n, 3, 3))], axis=2).reshape(3 * n, 6)
    b = -(np.einsum("nij,jk,nk->ni", R_bf, R_flange_cam, p_cam) + T[:, :3, 3]).reshape(3 * n)
    if np.linalg.svd(A / np.sqrt(n), compute_uv=False)[-1] < min_singular:
        return None
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    return x[:3], x[3:]


def intrinsics_of(points_cam: np.ndarray) -> np.ndarray | None:
    """(3, 3) pinhole K fitted to an organized camera-frame cloud (H, W, 3) (x/z = (u - cx)/fx,
    y/z = (v - cy)/fy); None with fewer than 20 valid points."""
    H, W, _ = points_cam.shape
    v, u = np.mgrid[0:H:8, 0:W:8]
    p = points_cam[::8, ::8]
    ok = np.isfinite(p).all(axis=2) & (p[..., 2] > 0)
    if ok.sum() < 20:
        return None
    kx, bx = np.polyfit(u[ok], p[ok][:, 0] / p[ok][:, 2], 1)
    ky, by = np.polyfit(v[ok], p[ok][:, 1] / p[ok][:, 2], 1)
    return np.array([[1.0 / kx, 0.0, -bx / kx], [0.0, 1.0 / ky, -by / ky], [0.0, 0.0, 1.0]])
