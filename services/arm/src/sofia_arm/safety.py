"""Safety rules on motion targets (joint margins, workspace box, the tool above the surface) and
inverse kinematics.

Every target is checked before anything moves; a broken rule raises a :class:`TargetRefused`
naming the pose, the value and the rule. The tool (:mod:`sofia_arm.tool`) is checked at the
target and along the motion's path: a straight line for ``move_pose``, the joint-space line for
``move_joints``. Compound commands check the whole sequence of their poses first
(:meth:`Safety.check_plan`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Literal

import numpy as np
from sofia_schemas import Board
from sofia_schemas.kinematics import joint_limits, panda_fk
from sofia_schemas.transforms import matrix_to_quat_xyzw

from . import poses
from .config import ArmConfig
from .errors import (
    BelowSurface,
    ConfigError,
    OutsideJointLimits,
    OutsideWorkspace,
    TargetRefused,
    Unreachable,
)
from .tool import Surface, Tool, joint_path, line_path

StepKind = Literal["joints", "line"]
LOOK_BELOW_M = 0.02  # a point to look at may lie this far below the surface (a blob on a thin sheet, noise)
LOOK_REACH_M = 0.4  # views from 0.3-0.6 m, tilted up to 40 deg, put the flange within this of the point

IK_ITERATIONS = 200
IK_DAMPING = 1e-3
FD_STEP = 1e-6


def rotation_vectors(R_a_b: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) (axis times angle, rad) of rotation matrices (..., 3, 3)."""
    q = matrix_to_quat_xyzw(R_a_b)
    s = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:4])
    return np.where(s > 1e-12, q[..., :3] / np.maximum(s, 1e-300) * angle, 2.0 * q[..., :3])


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


def tool_of(config: ArmConfig) -> Tool:
    """The configured tool: SofIA's fingers or a bare flange."""
    if config.tool == "flange":
        return Tool.bare_flange()
    return Tool.fingers(config.fingertip_offset_m, config.finger_half_width_m)


def surface_of(config: ArmConfig) -> Surface:
    """The configured surface: the board file's top when given, else the configured plane."""
    if config.board_file is None:
        return Surface(
            config.surface_z, config.surface_margin_m, f"configured plane z = {config.surface_z:g} m"
        )
    try:
        board = Board.from_file(config.board_file)
    except (OSError, ValueError) as e:
        raise ConfigError(f"arm config board_file {config.board_file}: {e}") from None
    return Surface(board.surface_z, config.surface_margin_m,
                   f"board {config.board_file}, surface_z = {board.surface_z:g} m")  # fmt: skip


def _rounded(p: np.ndarray) -> list[float]:
    return [round(float(v), 4) for v in p]


class Safety:
    """The configured rules: joint limits minus a margin, the workspace box of the flange, the tool
    (fingertips and finger envelope) above the surface plus a margin."""

    def __init__(self, config: ArmConfig) -> None:
        self.config = config
        q_min, q_max = joint_limits(config.model)
        self.q_low = q_min + config.joint_margin_rad
        self.q_high = q_max - config.joint_margin_rad
        self.box_min = np.array(config.workspace_min)
        self.box_max = np.array(config.workspace_max)
        self.tool = tool_of(config)
        self.surface = surface_of(config)
        self.reach = self.planner_reach(
            poses.Reach(config.joint_margin_rad, config.workspace_min, config.workspace_max)
        )

    def planner_reach(self, reach: poses.Reach) -> poses.Reach:
        """``reach`` (a planner's joint margin and box) with this robot's joint limits, this tool and
        surface."""
        points = tuple((float(x), float(y), float(z)) for x, y, z in self.tool.points_flange)
        return dataclasses.replace(reach, tool_points_flange=points, tool_lowest_z=self.surface.lowest_allowed,
                                   model=self.config.model)  # fmt: skip

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
                j + 1, float(q[j]), self.q_low[j], self.q_high[j], self.config.joint_margin_rad,
                "" if what == "move_joints target" else what,
            )  # fmt: skip
        return q

    def check_position(self, p_base: np.ndarray, what: str = "target") -> None:
        """OutsideWorkspace when the flange position p_base (3,) (base frame, m) leaves the box."""
        p = np.asarray(p_base, dtype=np.float64)
        if np.any(p < self.box_min) or np.any(p > self.box_max):
            raise OutsideWorkspace(what, _rounded(p), self.box_min.tolist(), self.box_max.tolist())

    def check_tool(self, T_base_flange: np.ndarray, what: str = "target") -> None:
        """BelowSurface when a point of the tool at any of the flange poses (n, 4, 4) or (4, 4)
        (base frame) comes closer to the surface than its margin; names the lowest point."""
        low, z = self.tool.lowest(T_base_flange)
        i = int(np.argmin(z))
        if z[i] < self.surface.lowest_allowed:
            t = self.tool
            name = ("flange" if t.name == "flange"
                    else f"fingers (fingertips {t.fingertip_offset_m:.3f} m along the flange z axis)")  # fmt: skip
            raise BelowSurface(what, name, _rounded(low[i]), self.surface.lowest_allowed, self.surface.source,
                               self.surface.margin_m)  # fmt: skip

    def check_joint_target(self, q: np.ndarray, q_from: np.ndarray | None = None,
                           what: str = "move_joints target") -> np.ndarray:  # fmt: skip
        """A checked joint target (7,): within the margins, its flange pose inside the box, the tool
        above the surface there and, given the start ``q_from`` (7,), all along the way."""
        q = self.check_joints(q, what)
        T = panda_fk(q, check_limits=False)
        self.check_position(T[:3, 3], what)
        self.check_tool(T, what)
        if q_from is not None:
            self.check_tool(joint_path(np.asarray(q_from, dtype=np.float64), q), f"{what} (on the way there)")
        return q

    def check_pose_target(self, T_base_flange: np.ndarray, q_seed: np.ndarray,
                          q_home: np.ndarray | None = None, what: str = "move_pose target") -> np.ndarray:  # fmt: skip
        """The joint positions (7,) reaching a checked flange pose (4, 4): inside the box, the tool
        above the surface there and along the straight line from the pose of ``q_seed`` (the
        current joints), reachable within the joint margins (from ``q_seed``, else ``q_home``)."""
        T = np.asarray(T_base_flange, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise TargetRefused(f"{what} must be a finite (4, 4) transform, got shape {T.shape}")
        R = T[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise TargetRefused(f"{what}: the rotation block is not a rotation")
        self.check_position(T[:3, 3], what)
        self.check_tool(T, what)
        self.check_tool(line_path(panda_fk(np.asarray(q_seed, dtype=np.float64), check_limits=False), T),
                        f"{what} (on the straight line there)")  # fmt: skip
        for seed in (q_seed, q_home):
            if seed is None:
                continue
            q = solve_ik(T, seed, self.q_low, self.q_high)
            if q is not None:
                return self.check_joints(q, what)
        raise Unreachable(
            f"{what}: flange pose at {_rounded(T[:3, 3])} m",
            f"no joint positions within the joint limits minus {self.config.joint_margin_rad} rad",
        )

    def check_plan(self, command: str, steps: Sequence[tuple[str, str, StepKind, np.ndarray]],
                   q_start: np.ndarray) -> dict[str, np.ndarray]:  # fmt: skip
        """Every pose of a compound command, checked before its first motion: ``steps`` are
        (motion, pose name, "joints" | "line", T_base_flange (4, 4)) in the order they are
        visited from the joints ``q_start`` (7,). Returns the joint positions (7,) of each motion;
        TargetRefused naming the command, the pose, the motion and the rule."""
        q_prev = np.asarray(q_start, dtype=np.float64)
        planned: dict[str, np.ndarray] = {}
        for name, pose, kind, T in steps:
            what = f"{command} pose '{pose}' ({name})"
            self.check_position(T[:3, 3], what)
            self.check_tool(T, what)
            if kind == "line":
                q = self.check_pose_target(T, q_prev, None, what)
            else:
                ik = poses.solve_ik(T, q_prev, self.reach)
                if not ik.ok:
                    raise Unreachable(f"{what}: flange pose at {_rounded(T[:3, 3])} m", ik.reason)
                q = self.check_joint_target(ik.q, q_prev, what)
            planned[name] = q
            q_prev = q
        return planned

    def check_look_target(self, p_base: np.ndarray, what: str, reach_m: float = LOOK_REACH_M) -> None:
        """TargetRefused when a point the camera is to look at from above (p_base (3,), base
        frame, m: the calibration blob) lies below the surface or farther than ``reach_m``
        horizontally from the workspace box (no view of it keeps the flange in the box)."""
        p = np.asarray(p_base, dtype=np.float64)
        if p[2] < self.surface.z - LOOK_BELOW_M:
            raise TargetRefused(f"{what} {_rounded(p)} m lies {self.surface.z - p[2]:.3f} m below the surface "
                                f"({self.surface.source}): the camera cannot see it from above")  # fmt: skip
        gap = np.maximum(np.maximum(self.box_min[:2] - p[:2], p[:2] - self.box_max[:2]), 0.0)
        if float(np.linalg.norm(gap)) > reach_m:
            raise OutsideWorkspace(f"{what} {_rounded(p)} m: every view of it puts the flange", "more than "
                                   f"{reach_m} m outside the box", self.box_min.tolist(), self.box_max.tolist())  # fmt: skip
