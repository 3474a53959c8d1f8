"""Plain 6-DoF target poses (a marker, a board's pose) with the flange poses: hand-eye from pose pairs.

Eye-in-hand: ``T_base_target = T_base_flange_i X T_cam_target_i``, X = T_flange_cam, the target
fixed in the base frame (eye-to-hand: the flange poses inverted, X = T_base_cam, the target on the
flange). OpenCV's ``calibrateHandEye`` (Tsai, Park, Horaud, Andreff, Daniilidis) and
``calibrateRobotWorldHandEye`` (``RW_SHAH``, ``RW_LI``) give the starts and the baselines; the best
is refined jointly over X and T_base_target on each view's pose discrepancy in the camera frame
(origin, metres; rotation, rad), each part weighted by its noise level estimated from the residuals
(a first pass weighs a rotation as the target's ``size_m``); the 1-sigma from the Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import OptimizeResult, least_squares
from scipy.spatial.transform import Rotation

from ..errors import InputMismatch, TooFewSamples
from ..fitting.diagnostics import std_from_covariance6

OPENCV_METHODS = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")
ROBOT_WORLD_METHODS = ("SHAH", "LI")  # calibrateRobotWorldHandEye: X and the target's pose together
DEFAULT_SIZE_M = 0.05
MIN_PAIRS = 3


@dataclass
class PoseFit:
    """X (eye-in-hand T_flange_cam, eye-to-hand T_base_cam) and the fixed target pose, metres."""

    X: np.ndarray  # (4, 4)
    T_fixed_target: np.ndarray  # (4, 4) target in the base (eye-in-hand) or flange (eye-to-hand) frame
    rms_m: float  # RMS residual of the target's origin, per axis, metres
    covariance6: np.ndarray  # (6, 6) of X: (t m, rot rad), parent axes (left perturbation)
    start: str  # the OpenCV method whose answer started the refinement
    baselines: dict[str, np.ndarray] = field(default_factory=dict)  # OpenCV method -> X (4, 4)

    @property
    def std_translation_mm(self) -> np.ndarray:
        """(3,) 1-sigma of X's translation, mm."""
        return std_from_covariance6(self.covariance6)[0]

    @property
    def std_rotation_deg(self) -> np.ndarray:
        """(3,) 1-sigma of X's rotation about its parent axes, degrees."""
        return std_from_covariance6(self.covariance6)[1]


def covariance6(sol: OptimizeResult, dof: int) -> np.ndarray:
    """(6, 6) covariance of X, (t m, rot rad about the parent axes), from a ``least_squares``
    result whose first 6 unknowns are X's (rot, t), its noise level from the residuals over ``dof``."""
    cov = np.linalg.pinv(sol.jac.T @ sol.jac) * (2.0 * sol.cost / dof)
    idx = [3, 4, 5, 0, 1, 2]  # (rot, t) of X -> (t, rot about the parent axes)
    return np.asarray(cov[np.ix_(idx, idx)])


def _validate(T_base_flange: np.ndarray, T_cam_target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    A, B = (np.asarray(x, dtype=np.float64) for x in (T_base_flange, T_cam_target))
    for name, M in (("T_base_flange", A), ("T_cam_target", B)):
        if M.ndim != 3 or M.shape[1:] != (4, 4) or not np.isfinite(M).all():
            raise InputMismatch(f"{name} must be finite (n, 4, 4), got shape {M.shape}")
    if len(A) != len(B):
        raise InputMismatch(f"{len(A)} flange poses but {len(B)} target poses")
    if len(A) < MIN_PAIRS:
        raise TooFewSamples(len(A), MIN_PAIRS)
    return A, B


def opencv_hand_eye(A: np.ndarray, B: np.ndarray) -> dict[str, np.ndarray]:
    """X by each of OpenCV's ``calibrateHandEye`` methods and its ``calibrateRobotWorldHandEye``
    ones (named ``RW_SHAH``, ``RW_LI``) from A (n, 4, 4) T_base_flange and B (n, 4, 4) T_cam_target
    (gripper2base, target2cam in OpenCV's words); methods that fail or return no rotation (a
    reflection) are left out."""
    import cv2

    out = {}
    for name in OPENCV_METHODS:
        try:
            R, t = cv2.calibrateHandEye(
                list(A[:, :3, :3]), list(A[:, :3, 3]), list(B[:, :3, :3]), list(B[:, :3, 3]),
                method=getattr(cv2, f"CALIB_HAND_EYE_{name}"),
            )  # fmt: skip
        except cv2.error:
            continue
        if (X := _rigid(R, t)) is not None:
            out[name] = X
    A_inv = np.linalg.inv(A)  # base2gripper; B is world2cam (the target as the world)
    for name in ROBOT_WORLD_METHODS:
        try:
            *_, R, t = cv2.calibrateRobotWorldHandEye(
                list(B[:, :3, :3]), list(B[:, :3, 3]), list(A_inv[:, :3, :3]), list(A_inv[:, :3, 3]),
                method=getattr(cv2, f"CALIB_ROBOT_WORLD_HAND_EYE_{name}"),
            )  # fmt: skip
        except cv2.error:
            continue
        if (T_cam_flange := _rigid(R, t)) is not None:
            out[f"RW_{name}"] = np.linalg.inv(T_cam_flange)
    return out


def _rigid(R: np.ndarray, t: np.ndarray) -> np.ndarray | None:
    """(4, 4) float64 from OpenCV's R (3, 3) and t (3, 1); None when not finite or R is no rotation
    (a failed method can return a reflection)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T if np.isfinite(T).all() and abs(np.linalg.det(T[:3, :3]) - 1.0) < 1e-3 else None


def fixed_target(A: np.ndarray, X: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(4, 4) the mean of A_i X B_i (rotation: SciPy's chordal mean)."""
    Y = A @ X @ B
    out = np.eye(4)
    out[:3, :3] = Rotation.from_matrix(Y[:, :3, :3]).mean().as_matrix()
    out[:3, 3] = Y[:, :3, 3].mean(axis=0)
    return out


def _unpack(x: np.ndarray, X0: np.ndarray, Y0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """X, Y perturbed on the left from X0, Y0: rotation exp(x[:3]) R0, translation t0 + x[3:6]."""
    X, Y = np.eye(4), np.eye(4)
    X[:3, :3], X[:3, 3] = Rotation.from_rotvec(x[:3]).as_matrix() @ X0[:3, :3], X0[:3, 3] + x[3:6]
    Y[:3, :3], Y[:3, 3] = Rotation.from_rotvec(x[6:9]).as_matrix() @ Y0[:3, :3], Y0[:3, 3] + x[9:12]
    return X, Y


def residuals(
    x: np.ndarray, X0: np.ndarray, Y0: np.ndarray, A_inv: np.ndarray, B: np.ndarray, w: np.ndarray
) -> np.ndarray:
    """(n * 6,) whitened pose discrepancy of each view, camera frame: (predicted minus measured
    target origin, metres; rotation vector of predicted R measured R^T, rad), times ``w`` (2,) the
    inverse noise of the translation and rotation parts; X, Y perturbed by x (12,) from X0, Y0."""
    X, Y = _unpack(x, X0, Y0)
    P = np.linalg.inv(X) @ A_inv @ Y  # (n, 4, 4) predicted T_cam_target
    dt = P[:, :3, 3] - B[:, :3, 3]
    dr = Rotation.from_matrix(P[:, :3, :3] @ np.swapaxes(B[:, :3, :3], 1, 2)).as_rotvec()
    return np.asarray(np.c_[w[0] * dt, w[1] * dr].ravel())


def hand_eye_from_poses(
    T_base_flange: np.ndarray,
    T_cam_target: np.ndarray,
    size_m: float = DEFAULT_SIZE_M,
    setup: str = "eye-in-hand",
) -> PoseFit:
    """Hand-eye from n pose pairs: T_base_flange (n, 4, 4) and T_cam_target (n, 4, 4), metres.

    setup "eye-in-hand": X = T_flange_cam, target fixed in the base; "eye-to-hand": X = T_base_cam,
    target on the flange. The OpenCV method's X of lowest cost starts the refinement.
    """
    A, B = _validate(T_base_flange, T_cam_target)
    if setup == "eye-to-hand":
        A = np.linalg.inv(A)
    elif setup != "eye-in-hand":
        raise InputMismatch(f"setup must be 'eye-in-hand' or 'eye-to-hand', got {setup!r}")
    base = opencv_hand_eye(A, B)
    if not base:
        raise InputMismatch("no OpenCV hand-eye method gave a transform: the poses may not rotate enough")
    A_inv = np.linalg.inv(A)
    w = np.array([1.0, 1.0 / size_m])  # first pass: a rotation weighs as the target's size
    # the start of lowest cost is refined (the methods' answers differ by millimetres, one basin)
    starts = {name: (X0, fixed_target(A, X0, B)) for name, X0 in base.items()}
    costs = {
        name: float(np.sum(residuals(np.zeros(12), X0, Y0, A_inv, B, w) ** 2))
        for name, (X0, Y0) in starts.items()
    }
    name = min(costs, key=costs.__getitem__)
    X, Y = starts[name]
    sol = least_squares(residuals, np.zeros(12), args=(X, Y, A_inv, B, w), x_scale=0.05)
    dof = max(6 * len(A) - 12, 1)
    for _ in range(3):  # the translation and rotation noise levels estimated from the residuals
        X, Y = _unpack(sol.x, X, Y)
        r = sol.fun.reshape(-1, 2, 3) / w[None, :, None]
        w = 1.0 / np.sqrt(np.maximum(np.sum(r**2, axis=(0, 2)) * 2.0 / dof, 1e-24))
        # re-anchored at the solution: the Jacobian is in its own left perturbation
        sol = least_squares(residuals, np.zeros(12), args=(X, Y, A_inv, B, w), x_scale=0.05)
    X, Y = _unpack(sol.x, X, Y)
    rms_m = float(np.sqrt(np.mean((sol.fun.reshape(-1, 2, 3)[:, 0] / w[0]) ** 2)))
    return PoseFit(X, Y, rms_m, covariance6(sol, dof), name, base)


def consistency(
    T_base_flange: np.ndarray, T_cam_target: np.ndarray, X: np.ndarray, setup: str = "eye-in-hand"
) -> tuple[float, float]:
    """How well X explains pose pairs without truth: (RMS target-origin discrepancy, metres; RMS
    rotation discrepancy, rad) between each measured T_cam_target and the one predicted through X
    and the fixed target of X (:func:`fixed_target`, the mean over the views)."""
    A, B = _validate(T_base_flange, T_cam_target)
    A = np.linalg.inv(A) if setup == "eye-to-hand" else A
    r = residuals(np.zeros(12), X, fixed_target(A, X, B), np.linalg.inv(A), B, np.ones(2)).reshape(-1, 2, 3)
    return float(np.sqrt(np.mean(r[:, 0] ** 2))), float(np.sqrt(np.mean(r[:, 1] ** 2)))
