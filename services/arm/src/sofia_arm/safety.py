"""Safety rules on motion targets (joint margins, workspace box) and inverse kinematics.

Every target is checked before anything moves; a broken rule raises a :class:`TargetRefused`
naming the value and the rule.
"""

from __future__ import annotations

import numpy as np
from sofia_schemas.kinematics import joint_limits, panda_fk, rotation_to_quat_xyzw

from .config import ArmConfig
from .errors import OutsideJointLimits, OutsideWorkspace, TargetRefused, Unreachable

IK_ITERATIONS = 200
IK_DAMPING = 1e-3
FD_STEP = 1e-6


def rotation_vectors(R_a_b: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) (axis times angle, rad) of rotation matrices (..., 3, 3)."""
    q = rotation_to_quat_xyzw(R_a_b)
    s = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:4])
    return np.where(s > 1e-12, q[..., :3] / np.maximum(s, 1e-300) * angle, 2.0 * q[..., :3])


def pose_error(T_target: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    """(translation error m, rotation error deg) between two (4, 4) poses."""
    dp = float(np.linalg.norm(T_target[:3, 3] - T[:3, 3]))
    dr = float(np.linalg.norm(rotation_vectors(T_target[:3, :3] @ T[:3, :3].T)))
    return dp, float(np.degrees(dr))


def _twist_error(T_target: np.ndarray, Ts: np.ndarray) -> np.ndarray:
    """(n, 6) error from poses Ts (n, 4, 4) to T_target, base frame: translation, rotation vector."""
    dp = T_target[:3, 3] - Ts[:, :3, 3]
    dr = rotation_vectors(T_target[:3, :3] @ np.transpose(Ts[:, :3, :3], (0, 2, 1)))
    return np.concatenate([dp, dr], axis=1)


def solve_ik(T_base_flange: np.ndarray, q_seed: np.ndarray, q_min: np.ndarray, q_max: np.ndarray,
             tol_m: float = 1e-6, tol_rad: float = 1e-6) -> np.ndarray | None:  # fmt: skip
    """Joint positions (7,) whose flange pose is ``T_base_flange`` (4, 4), base frame, found by damped
    least squares from ``q_seed`` (7,) within [q_min, q_max]; None when it does not converge."""
    q = np.clip(np.asarray(q_seed, dtype=np.float64), q_min, q_max)
    eye = np.eye(7)
    for _ in range(IK_ITERATIONS):
        qs = np.vstack([q, q + FD_STEP * eye])  # (8, 7): the point and one step per joint
        Ts = panda_fk(qs, check_limits=False)
        errs = _twist_error(T_base_flange, Ts)
        e = errs[0]
        if np.linalg.norm(e[:3]) < tol_m and np.linalg.norm(e[3:]) < tol_rad:
            return q
        J = (errs[0] - errs[1:]).T / FD_STEP  # (6, 7): d(pose)/dq
        dq = J.T @ np.linalg.solve(J @ J.T + IK_DAMPING**2 * np.eye(6), e)
        step = np.linalg.norm(dq)
        if step > 0.2:
            dq *= 0.2 / step
        q = np.clip(q + dq, q_min, q_max)
    return None


class Safety:
    """The configured rules: joint limits minus a margin, the workspace box of the flange."""

    def __init__(self, config: ArmConfig) -> None:
        self.config = config
        q_min, q_max = joint_limits(config.model)
        self.q_low = q_min + config.joint_margin_rad
        self.q_high = q_max - config.joint_margin_rad
        self.box_min = np.array(config.workspace_min)
        self.box_max = np.array(config.workspace_max)

    def check_joints(self, q: np.ndarray, what: str = "target") -> np.ndarray:
        """``q`` as a float64 (7,) array; TargetRefused when malformed or outside limits minus margin."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (7,):
            raise TargetRefused(f"{what}: joint positions must be 7 values in radians, got shape {q.shape}")
        if not np.all(np.isfinite(q)):
            raise TargetRefused(f"{what}: joint positions {q.tolist()} are not all finite")
        bad = np.flatnonzero((q < self.q_low) | (q > self.q_high))
        if bad.size:
            j = int(bad[0])
            raise OutsideJointLimits(
                j + 1, float(q[j]), self.q_low[j], self.q_high[j], self.config.joint_margin_rad
            )
        return q

    def check_position(self, p_base: np.ndarray, what: str = "target") -> None:
        """OutsideWorkspace when the flange position p_base (3,) (base frame, m) leaves the box."""
        p = np.asarray(p_base, dtype=np.float64)
        if np.any(p < self.box_min) or np.any(p > self.box_max):
            fmt = [round(float(v), 4) for v in p]
            raise OutsideWorkspace(what, fmt, self.box_min.tolist(), self.box_max.tolist())

    def check_joint_target(self, q: np.ndarray) -> np.ndarray:
        """A checked joint target (7,): within the margins, its flange pose inside the box."""
        q = self.check_joints(q, "move_joints target")
        self.check_position(panda_fk(q, check_limits=False)[:3, 3], "move_joints target")
        return q

    def check_pose_target(self, T_base_flange: np.ndarray, q_seed: np.ndarray,
                          q_home: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        """The joint positions (7,) reaching a checked flange pose (4, 4): inside the box, reachable
        within the joint margins (from ``q_seed``, else from ``q_home``)."""
        T = np.asarray(T_base_flange, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise TargetRefused(f"move_pose target must be a finite (4, 4) transform, got shape {T.shape}")
        R = T[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise TargetRefused("move_pose target: the rotation block is not a rotation")
        self.check_position(T[:3, 3], "move_pose target")
        for seed in (q_seed, q_home):
            if seed is None:
                continue
            q = solve_ik(T, seed, self.q_low, self.q_high)
            if q is not None:
                return self.check_joints(q, "move_pose target")
        p = [round(float(v), 4) for v in T[:3, 3]]
        raise Unreachable(
            f"flange pose at {p} m",
            f"no joint positions within the joint limits minus {self.config.joint_margin_rad} rad",
        )
