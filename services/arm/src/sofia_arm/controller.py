"""Motion with safety checks, stop, preemption, time-outs and a fine correction at the end.

Each command runs under a :class:`Token`. A newer command cancels the running one's token
(``preempted``), ``stop`` cancels it with ``stopped``, its deadline with ``timeout``; the motion loop
notices within one poll period, brings the robot to a stop and returns that status.

After a trajectory ends and the arm is still, the measured flange pose (Panda FK of the measured
joints, averaged over 0.2 s of the robot's clock) is compared with the target; while it is farther
than half the tolerance a small joint correction (the remaining error added to the command,
approached from below) is commanded, at most ``max_corrections`` times. ``done``: within the tolerance.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import franky
import numpy as np
from sofia_schemas.kinematics import joint_limits, panda_fk
from sofia_schemas.messages import ArmCommandName, ArmResult, ArmStatus
from sofia_schemas.transforms import matrix_to_quat_xyzw, pose_gap

from .command_token import Token
from .config import ArmConfig
from .errors import NotReady
from .robot import RobotLink, stop_motion
from .safety import Safety, solve_ik

log = logging.getLogger(__name__)
POLL_S = 0.01
HALT_TIMEOUT_S = 5.0
APPROACH_RAD = 0.02  # corrections come from this far below the command, on every joint
SETTLE_S = 0.3  # after a motion, wait this much of the robot's clock (the joints' servo settles) ...
SETTLE_MEAN_S = 0.2  # ... then average the joint positions over this much
FAULT_MODES = {"Reflex", "UserStopped", "AutomaticErrorRecovery", "Other"}
# A motion without a new robot state for this long, the link up, is stuck (a dead link: libfranka's UDP time-out)
STATE_SILENCE_S = 5.0
# Robot time between one motion's end and the next one's start: without it franky-sim read the last
# motion's late finish command as ending the next Move, and libfranka waited forever for a reply.
MOTION_GAP_S = 0.02


class Controller:
    """Moves the arm of a :class:`RobotLink` within the rules of an :class:`ArmConfig`."""

    def __init__(self, link: RobotLink, config: ArmConfig, gripper_error: Callable[[], str | None]) -> None:
        self.link = link
        self.config = config
        self.safety = Safety(config)
        self.gripper_error = gripper_error
        self.q_min, self.q_max = joint_limits(config.model)
        self._lock = threading.Lock()
        self.current: Token | None = None
        self.last_command: ArmCommandName | None = None
        self.last_result: ArmResult | None = None
        self._motion_ended_ns = -1  # robot time at which the last motion ended

    # --- commands' lives ----------------------------------------------------
    def begin(self, command: ArmCommandName, timeout_s: float) -> Token:
        """A token for a new command; the running command (if any) is preempted."""
        with self._lock:
            if self.current is not None:
                self.current.cancel("preempted", f"preempted by a {command} command")
            self.current = Token(command, timeout_s)
            self.last_command = command
            return self.current

    def finish(self, token: Token, result: ArmResult) -> None:
        with self._lock:
            if self.current is token:
                self.current = None
            self.last_result = result

    def cancel_current(self, status: ArmStatus, reason: str) -> None:
        with self._lock:
            if self.current is not None:
                self.current.cancel(status, reason)

    # --- checks -------------------------------------------------------------
    def ready(self) -> franky.Robot:
        """The robot when it may move; NotReady saying why not."""
        robot = self.link.robot
        if robot is None:
            raise NotReady(self.link.error or f"not connected to the robot at {self.link.host}")
        if self.link.error:
            raise NotReady(f"{self.link.error} (send recover)")
        s = self.link.latest
        if s is not None and s.errors:
            raise NotReady(f"the robot reports errors {s.errors} (send recover)")
        if s is not None and s.robot_mode in FAULT_MODES:
            raise NotReady(f"the robot is in mode {s.robot_mode} (release the user stop, then send recover)")
        gripper = self.gripper_error()
        if gripper:
            raise NotReady(f"the gripper service reports an error: {gripper}")
        return robot

    def factor(self, speed: float) -> franky.RelativeDynamicsFactor:
        c = self.config
        return franky.RelativeDynamicsFactor(min(speed, c.max_velocity), min(speed, c.max_acceleration),
                                             min(speed, c.max_jerk))  # fmt: skip

    # --- results ------------------------------------------------------------
    def result(self, command: ArmCommandName, status: ArmStatus, reason: str, started: float) -> ArmResult:
        """An ArmResult with the measured pose (joints averaged over 0.1 s)."""
        q = self.link.mean_q(0.1)
        fields: dict[str, object] = {}
        if q is not None:
            T = panda_fk(q, check_limits=False)
            fields = {"q": tuple(float(v) for v in q), "position": tuple(float(v) for v in T[:3, 3]),
                      "quaternion_xyzw": tuple(float(v) for v in matrix_to_quat_xyzw(T[:3, :3]))}  # fmt: skip
        return ArmResult.model_validate({
            "ok": status == "done", "command": command, "status": status, "reason": reason,
            "duration_s": time.monotonic() - started, **fields,
        })  # fmt: skip

    # --- motion -------------------------------------------------------------
    def halt(self, robot: franky.Robot | None = None) -> None:
        """Bring a moving robot to a stop (a stop motion of the running control type)."""
        robot = robot or self.link.robot
        if robot is not None:
            stop_motion(robot, self.config.stop_dynamics)

    def _run(self, token: Token, robot: franky.Robot, motion: object) -> tuple[ArmStatus, str] | None:
        """Run ``motion`` until it ends; None when it finished, else (status, reason).

        A motion during which no new robot state arrives for ``STATE_SILENCE_S`` is stopped; when
        the robot then sends states again, the motion counts as ended (the caller measures where
        the arm is), else the connection is lost. It starts ``MOTION_GAP_S`` after the last one ended."""
        try:
            if self._wait_motion_gap(token):
                return token.status or "failed", token.reason
            robot.move(motion, asynchronous=True)  # type: ignore[call-overload]
            heard = (self._robot_ns(), time.monotonic())
            while True:
                if token.ended():
                    self.halt(robot)
                    self._join_quietly(robot)
                    return token.status or "failed", token.reason
                if robot.join_motion(timeout=POLL_S):
                    return None
                now_ns = self._robot_ns()
                if now_ns != heard[0]:
                    heard = (now_ns, time.monotonic())
                elif time.monotonic() - heard[1] > STATE_SILENCE_S:
                    return self._unstick(robot, token)
        except Exception as e:  # franky's ControlException, NetworkException, ...
            reason = f"{type(e).__name__}: {e}"
            if isinstance(e, franky.NetworkException):
                self.link.lost(reason)
            log.warning("%s failed: %s", token.command, reason)
            return "failed", reason
        finally:
            self._motion_ended_ns = self._robot_ns()

    def _wait_motion_gap(self, token: Token) -> bool:
        """Wait until the robot's clock is ``MOTION_GAP_S`` past the last motion's end; True if the command ended."""
        gap_ns = self._motion_ended_ns + int(MOTION_GAP_S * 1e9) - self._robot_ns()
        if gap_ns > 0:
            self.wait_robot_time(token, gap_ns / 1e9)
        return token.ended()

    def _robot_ns(self) -> int:
        latest = self.link.latest
        return latest.robot_time_ns if latest is not None else -1

    def _unstick(self, robot: franky.Robot, token: Token) -> tuple[ArmStatus, str] | None:
        """Stop a motion that stopped receiving robot states; None when states come back."""
        log.warning(
            "%s: no robot state for %g s during a motion: stopping it", token.command, STATE_SILENCE_S
        )
        try:
            robot.stop()
        except Exception as e:
            log.warning("stopping the stuck motion: %s", e)
        self._join_quietly(robot)
        if self.link.wait_sample(time.time_ns(), HALT_TIMEOUT_S) is None:
            reason = (
                f"the robot sent no state for {STATE_SILENCE_S:g} s during a motion, nor after stopping it"
            )
            self.link.lost(reason)
            return "failed", reason
        log.info("%s: the robot answers again; measuring where the arm is", token.command)
        return None

    def _join_quietly(self, robot: franky.Robot) -> None:
        try:
            robot.join_motion(timeout=HALT_TIMEOUT_S)
        except Exception as e:
            log.info("motion ended with %s", e)

    def wait_still(self, token: Token | None, timeout_s: float) -> bool:
        """Wait until the arm is still; False on cancellation or after ``timeout_s`` of the robot's clock
        (a simulator slower than real time gets the same physical time), at most 20x that of wall time."""
        wall_deadline = time.monotonic() + 20 * timeout_s
        start = self.link.latest
        robot_deadline = (start.robot_time_ns if start else 0) + int(timeout_s * 1e9)
        while time.monotonic() < wall_deadline:
            if token is not None and token.ended():
                return False
            if self.link.is_still(self.config.still_speed_rad_s):
                return True
            latest = self.link.latest
            if start is not None and latest is not None and latest.robot_time_ns > robot_deadline:
                return False
            time.sleep(POLL_S)
        return False

    def wait_robot_time(self, token: Token, seconds: float) -> None:
        """Wait until the robot's clock has advanced by ``seconds`` (or the token ended)."""
        start = self.link.latest
        if start is None:
            return
        end = start.robot_time_ns + int(seconds * 1e9)
        wall_deadline = time.monotonic() + 50 * seconds
        while not token.ended() and time.monotonic() < wall_deadline:
            latest = self.link.latest
            if latest is not None and latest.robot_time_ns >= end:
                return
            time.sleep(POLL_S)

    def move_joints(
        self, token: Token, q: np.ndarray, speed: float, command: ArmCommandName = "move_joints"
    ) -> ArmResult:
        """Move to joint positions q (7,) rad. Raises TargetRefused / NotReady before moving."""
        started = time.monotonic()
        robot = self.ready()
        q_goal = self.safety.check_joint_target(q, getattr(self.link.latest, "q", None), f"{command} target")
        f = self.factor(speed)
        ended = self._run(token, robot, franky.JointMotion(q_goal, relative_dynamics_factor=f))
        if ended is not None:
            return self.result(command, ended[0], ended[1], started)
        T_goal = panda_fk(q_goal, check_limits=False)  # within the configured robot's limits (checked above)
        return self._settle(token, robot, T_goal, lambda _q: q_goal, f, command, started)

    def move_pose(self, token: Token, T_base_flange: np.ndarray, speed: float) -> ArmResult:
        """Move the flange in a straight line to T_base_flange (4, 4), base frame."""
        started = time.monotonic()
        robot = self.ready()
        s = self.link.latest
        if s is None:
            raise NotReady("no robot state received yet")
        T_goal = np.asarray(T_base_flange, dtype=np.float64)
        self.safety.check_pose_target(T_goal, s.q, np.array(self.config.home_q))
        f = self.factor(speed)
        T_ee = T_goal @ s.F_T_EE  # franky moves the end effector: flange pose times flange -> EE
        motion = franky.CartesianMotion(franky.Affine(T_ee), franky.ReferenceType.Absolute, f)
        ended = self._run(token, robot, motion)
        if ended is not None:
            return self.result("move_pose", ended[0], ended[1], started)

        goal: list[np.ndarray] = []

        def q_goal(q_meas: np.ndarray) -> np.ndarray:  # the joint solution nearest where it arrived, kept
            if not goal:
                q = solve_ik(T_goal, q_meas, self.q_min, self.q_max)
                goal.append(q_meas if q is None else q)
            return goal[0]

        return self._settle(token, robot, T_goal, q_goal, f, "move_pose", started)

    def _settle(self, token: Token, robot: franky.Robot, T_goal: np.ndarray,
                q_goal_of: Callable[[np.ndarray], np.ndarray], f: franky.RelativeDynamicsFactor,
                command: ArmCommandName, started: float) -> ArmResult:  # fmt: skip
        """Wait until still and correct the remaining error (see the module docstring)."""
        c = self.config
        q_cmd: np.ndarray | None = None
        dp, dr = np.inf, np.inf
        for i in range(c.max_corrections + 1):
            self.wait_robot_time(token, SETTLE_S)
            still = self.wait_still(token, c.settle_timeout_s)
            self.wait_robot_time(token, SETTLE_MEAN_S)  # the mean below sees only settled states
            if token.ended():
                return self.result(command, token.status or "failed", token.reason, started)
            if not still:
                log.warning("%s: the arm did not come to rest within %g s", command, c.settle_timeout_s)
            q_meas = self.link.mean_q(SETTLE_MEAN_S)
            assert q_meas is not None
            dp, dr = pose_gap(T_goal, panda_fk(q_meas, check_limits=False))
            dr = np.degrees(dr)
            fine = dp <= c.position_tolerance_m / 2 and dr <= c.rotation_tolerance_deg / 2
            if fine or i == c.max_corrections or not still:
                break
            q_goal = q_goal_of(q_meas)
            q_cmd = np.clip((q_goal if q_cmd is None else q_cmd) + (q_goal - q_meas), self.q_min, self.q_max)
            log.info("%s correction %d: %.3f mm, %.4f deg from the target", command, i + 1, dp * 1e3, dr)
            # approached from below every time: joints with friction settle on the side they came from
            # (franky-sim's wrist about 1.8 mrad), so the corrections see the same offset each time
            for q in (np.clip(q_cmd - APPROACH_RAD, self.q_min, self.q_max), q_cmd):
                ended = self._run(token, robot, franky.JointMotion(q, relative_dynamics_factor=f))
                if ended is not None:
                    return self.result(command, ended[0], ended[1], started)
        if dp <= c.position_tolerance_m and dr <= c.rotation_tolerance_deg:
            return self.result(
                command, "done", f"reached: {dp * 1e3:.2f} mm, {dr:.3f} deg from the target", started
            )
        return self.result(command, "failed", f"stopped {dp * 1e3:.2f} mm, {dr:.3f} deg from the target "
                           f"(tolerance {c.position_tolerance_m * 1e3:g} mm, {c.rotation_tolerance_deg:g} deg)", started)  # fmt: skip
