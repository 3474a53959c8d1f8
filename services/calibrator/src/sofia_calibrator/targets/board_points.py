"""A ChArUco board's corners with depth: several points of known layout per view.

View i gives each detected corner j (``cv2.aruco.CharucoDetector``) its 3D point ``p_cam_ij``
(camera frame) from the organized cloud; with the layout ``q_j`` (board frame)::

    p_cam_ij = X^-1 A_i^-1 Y q_j      X = T_flange_cam, A_i = T_base_flange_i, Y = T_base_board

(eye-to-hand: the flange poses inverted), solved by :func:`scipy.optimize.least_squares` from the
pose-target fit (:func:`~.poses.hand_eye_from_poses`), residuals whitened by the D435 noise model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..errors import InputMismatch
from ..fitting.noise import camera_sigma
from .charuco import MIN_CORNERS, BoardNotFound, BoardSpec
from .poses import PoseFit, _unpack, covariance6

DEFAULT_BOARD = BoardSpec()


@dataclass
class CornerPoints:
    """One view's corners with depth: board corner ids (m,) and their points p_cam (m, 3), camera
    optical frame, metres."""

    ids: np.ndarray
    p_cam: np.ndarray


def corner_points(
    images: list[np.ndarray], clouds_cam: list[np.ndarray], spec: BoardSpec = DEFAULT_BOARD
) -> list[CornerPoints]:
    """The corners with depth of n views: grey images (h, w) uint8 and organized clouds (h, w, 3)
    (camera frame, metres, NaN where missing, registered to the images). A corner's point is the
    cloud's at its nearest pixel; corners without depth are left out. Raises :class:`BoardNotFound`
    for a view with fewer than ``MIN_CORNERS`` corners with depth."""
    import cv2

    if len(images) != len(clouds_cam):
        raise InputMismatch(f"{len(images)} images but {len(clouds_cam)} clouds")
    detector = cv2.aruco.CharucoDetector(spec.board())
    out = []
    for i, (img, cloud) in enumerate(zip(images, clouds_cam, strict=True)):
        cloud = np.asarray(cloud, dtype=np.float64)
        if cloud.ndim != 3 or cloud.shape[:2] != np.shape(img)[:2]:
            raise InputMismatch(
                f"view {i}: the cloud must be organized like its image {np.shape(img)[:2]}, got {cloud.shape}"
            )
        corners, ids, _, _ = detector.detectBoard(img)
        if ids is None:
            raise BoardNotFound(i, 0)
        uv = np.rint(corners.reshape(-1, 2)).astype(int)
        h, w = cloud.shape[:2]
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        p = np.full((len(uv), 3), np.nan)
        p[inside] = cloud[uv[inside, 1], uv[inside, 0]]
        ok = np.isfinite(p).all(axis=1)
        if ok.sum() < MIN_CORNERS:
            raise BoardNotFound(i, int(ok.sum()))
        out.append(CornerPoints(ids.ravel()[ok], p[ok]))
    return out


def _residuals(x: np.ndarray, X0: np.ndarray, Y0: np.ndarray, A_inv: np.ndarray, view: np.ndarray,
               q_board: np.ndarray, p_cam: np.ndarray, w: np.ndarray) -> np.ndarray:  # fmt: skip
    """(m * 3,) whitened predicted minus measured corner points (camera frame) of all views."""
    X, Y = _unpack(x, X0, Y0)
    T = np.linalg.inv(X)[None] @ A_inv @ Y[None]  # (n, 4, 4) T_cam_board per view
    pred = np.einsum("mij,mj->mi", T[view, :3, :3], q_board) + T[view, :3, 3]
    return np.asarray(((pred - p_cam) * w).ravel())


def board_points_fit(
    T_base_flange: np.ndarray, views: list[CornerPoints], start: PoseFit, spec: BoardSpec = DEFAULT_BOARD,
    setup: str = "eye-in-hand",
) -> PoseFit:  # fmt: skip
    """X and the board's pose from every corner with depth of every view, refined from ``start``
    (the pose-target fit of the same views). T_base_flange: (n, 4, 4); views: n views' corners.
    Returns a :class:`PoseFit` (rms_m: the corners' RMS residual per axis; 1-sigma from the
    Jacobian with the residual scale)."""
    A = np.asarray(T_base_flange, dtype=np.float64)
    if len(A) != len(views):
        raise InputMismatch(f"{len(A)} flange poses but {len(views)} views of the board")
    A = np.asarray(np.linalg.inv(A), dtype=np.float64) if setup == "eye-to-hand" else A
    layout = np.asarray(spec.board().getChessboardCorners(), dtype=np.float64)
    view = np.concatenate([np.full(len(v.ids), i) for i, v in enumerate(views)])
    q = layout[np.concatenate([v.ids for v in views])]
    p = np.concatenate([v.p_cam for v in views])
    w = 1.0 / camera_sigma(p)  # (m, 3) the D435 model's 1/sigma per camera axis
    args = (start.X, start.T_fixed_target, np.linalg.inv(A), view, q, p, w)
    sol = least_squares(_residuals, np.zeros(12), args=args, x_scale=0.05)
    X, Y = _unpack(sol.x, start.X, start.T_fixed_target)
    sol = least_squares(_residuals, np.zeros(12), args=(X, Y, *args[2:]), x_scale=0.05)  # re-anchored
    X, Y = _unpack(sol.x, X, Y)
    rms_m = float(np.sqrt(np.mean((sol.fun.reshape(-1, 3) / w) ** 2)))
    return PoseFit(X, Y, rms_m, covariance6(sol, max(3 * len(p) - 12, 1)),
                   f"{start.start}, then the corners with depth", start.baselines)  # fmt: skip
