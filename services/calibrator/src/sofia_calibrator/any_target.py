"""One call for every target and set-up: ``calibrate_target(target, setup, ...)`` returns the same
:class:`Calibration` (message, YAML, ROS launch line, TF, plot) for a blob or a sphere (points), a
ChArUco board or an AprilTag (a pose per view) or plain 6-DoF target poses (:mod:`.targets.poses`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputMismatch
from .eye_to_hand import BASE_FRAME, CAMERA_FRAME, SETUPS, calibrate_setup, flange_base_poses
from .fitting import diagnostics as dg
from .fitting.calibrate import CHILD_FRAME, PARENT_FRAME, Calibration
from .targets.apriltag import TagSpec, tag_poses
from .targets.board_points import board_points_fit, corner_points
from .targets.charuco import BoardSpec, board_poses
from .targets.poses import DEFAULT_SIZE_M, PoseFit, fixed_target, hand_eye_from_poses, residuals
from .targets.sphere import DEFAULT_INLIER_M
from .targets.sphere_shared import sphere_centres

TARGETS = ("blob", "sphere", "poses", "charuco", "apriltag")


def frames(setup: str) -> tuple[str, str]:
    """Default (parent, child) frames of a set-up's result."""
    return (BASE_FRAME, CAMERA_FRAME) if setup == "eye-to-hand" else (PARENT_FRAME, CHILD_FRAME)


def calibrate_target(
    target: str = "blob",
    setup: str = "eye-in-hand",
    *,
    T_base_flange: np.ndarray,
    p_cam: np.ndarray | None = None,
    clouds_cam: list[np.ndarray] | None = None,
    radius_m: float | None = None,
    inlier_m: float = DEFAULT_INLIER_M,
    T_cam_target: np.ndarray | None = None,
    size_m: float = DEFAULT_SIZE_M,
    images: list[np.ndarray] | None = None,
    K: np.ndarray | None = None,
    board: BoardSpec | None = None,
    tag: TagSpec | None = None,
    parent_frame: str | None = None,
    child_frame: str | None = None,
    **options: Any,
) -> Calibration:
    """Calibrate from any target in either set-up.

    T_base_flange: (n, 4, 4) flange poses. target "blob": p_cam (n, 3) camera frame, metres;
    "sphere": clouds_cam, n clouds (m_i, 3) camera frame, metres, the sphere of ``radius_m`` (None:
    one radius fitted to all the views) found in each; "poses": T_cam_target (n, 4, 4) measured target poses (``size_m``: the
    target's size, weighting a rotation in the first pass); "charuco": grey images (h, w) uint8, the
    camera matrix K (3, 3) and the ``board`` (:class:`BoardSpec`), each view's board pose by PnP
    on its ChArUco corners, then as "poses" (with ``clouds_cam``, organized (h, w, 3) clouds
    registered to the images: refined on every corner's 3D point, :mod:`.targets.board_points`); "apriltag": the same with the ``tag``
    (:class:`TagSpec`), each view's tag pose by PnP on its four corners. setup: "eye-in-hand" (result
    T_flange_cam) or "eye-to-hand" (result T_base_cam). options: those of :func:`calibrate` (for
    points). Returns a :class:`Calibration` with the set-up's frames unless given.
    """
    if target not in TARGETS:
        raise InputMismatch(f"target must be one of {TARGETS}, got {target!r}")
    if setup not in SETUPS:
        raise InputMismatch(f"setup must be one of {SETUPS}, got {setup!r}")
    parent, child = frames(setup)
    parent, child = parent_frame or parent, child_frame or child
    if target in ("charuco", "apriltag"):
        if images is None or K is None:
            raise InputMismatch(
                f"target {target!r} needs images (one per flange pose) and K, the camera matrix"
            )
        if target == "apriltag":
            tag = tag or TagSpec()
            T_cam_target, size_m = tag_poses(images, K, tag), tag.side_m
        else:
            spec = board or BoardSpec()
            T_cam_target, size_m = board_poses(images, K, spec), max(spec.size_m)
            if clouds_cam is not None:  # the corners with depth refine the board poses' fit
                start = hand_eye_from_poses(T_base_flange, T_cam_target, size_m, setup)
                fit = board_points_fit(
                    T_base_flange, corner_points(images, clouds_cam, spec), start, spec, setup
                )
                return pose_calibration(fit, T_base_flange, T_cam_target, setup, parent, child)
        target = "poses"
    if target == "poses":
        if T_cam_target is None:
            raise InputMismatch("target 'poses' needs T_cam_target (n, 4, 4), the measured target poses")
        fit = hand_eye_from_poses(T_base_flange, T_cam_target, size_m, setup)
        return pose_calibration(fit, T_base_flange, T_cam_target, setup, parent, child)
    if target == "sphere":
        if clouds_cam is None:
            raise InputMismatch("target 'sphere' needs clouds_cam, one point cloud per flange pose")
        p_cam = sphere_centres(clouds_cam, radius_m, inlier_m)[0]
    if p_cam is None:
        raise InputMismatch("target 'blob' needs p_cam (n, 3), the blob in the camera frame")
    return calibrate_setup(p_cam, T_base_flange, setup, parent_frame=parent, child_frame=child, **options)


def pose_calibration(
    fit: PoseFit, T_base_flange: np.ndarray, T_cam_target: np.ndarray, setup: str, parent: str, child: str
) -> Calibration:
    """The :class:`Calibration` of a pose fit: the target's origin plays the blob (its spread,
    residuals and mapped positions in the fixed frame), the covariance is the pose fit's."""
    A = np.asarray(T_base_flange, dtype=np.float64)
    A = flange_base_poses(A) if setup == "eye-to-hand" else A
    B = np.asarray(T_cam_target, dtype=np.float64)
    origins = (A @ fit.X @ B)[:, :3, 3]  # the target origin of each view in the fixed frame
    start = (A @ B)[:, :3, 3]  # through the identity
    r = residuals(np.zeros(12), fit.X, fixed_target(A, fit.X, B), np.linalg.inv(A), B, np.ones(2)).reshape(
        -1, 2, 3
    )
    res_mm = 1e3 * np.linalg.norm(r[:, 0], axis=1)
    n = len(A)
    warnings = dg.check_motion(A)
    return Calibration(
        T_flange_cam=fit.X, p_base=fit.T_fixed_target[:3, 3], samples=list(range(n)), mapped_base=origins,
        mapped_start=start, residuals_mm=res_mm, spread_mm=1e3 * dg.spread(origins),
        dissipation_before=dg.dissipation(start), dissipation_after=dg.dissipation(origins),
        std_translation_mm=fit.std_translation_mm, std_rotation_deg=fit.std_rotation_deg, covariance=fit.covariance6,
        noise_scale=1.0, n_iter=0, covariance6=fit.covariance6, noise_mm=1e3 * fit.rms_m,
        inliers=list(range(n)), leave_one_out_mm=res_mm, warnings=warnings,
        p_cam=B[:, :3, 3], T_base_flange=A,
        correction_reason=f"pose target: refined from OpenCV's {fit.start} (no depth correction)",
        parent_frame=parent, child_frame=child,
    )  # fmt: skip
