"""Arm commands: check, run under a token, answer with an :class:`ArmResult`.

``stop`` runs at once on the caller's thread (it always wins); every other command first passes
its checks (a refused target never disturbs a running motion), then preempts the running command
and runs on the command thread. ``pick_place`` and ``calibrate`` run ``sofia_arm.pick_place`` and
``sofia_arm.autocal`` with a :class:`CommandMotion` bound to their token.
"""

from __future__ import annotations

import importlib
import logging
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np
import zenoh
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ArmCommand, ArmCommandName, ArmResult
from sofia_schemas.transforms import make_transform

from .controller import HALT_TIMEOUT_S, Controller, Token
from .errors import ArmError, NotReady, TargetRefused, Unavailable
from .safety import Safety

log = logging.getLogger(__name__)
RECOVER_TIMEOUT_S = 10.0
COMPOUND = {"pick_place": ("sofia_arm.pick_place", "run_pick_place"),
            "calibrate": ("sofia_arm.autocal", "run_autocal"),
            "sort_colours": ("sofia_arm.sort", "run_sort")}  # fmt: skip


def load_compound(command: str) -> Callable[..., ArmResult]:
    """The function running a compound command; Unavailable naming the module when it is missing."""
    module_name, func = COMPOUND[command]
    try:
        module: ModuleType = importlib.import_module(module_name)
        return getattr(module, func)  # type: ignore[no-any-return]
    except (ImportError, AttributeError) as e:
        raise Unavailable(command, f"{module_name} ({func})", e) from None


class CommandMotion:
    """The :class:`~sofia_arm.motion.ArmMotion` given to a compound command, bound to its token:
    refused targets come back as ``failed`` results, and after a stop, preemption or time-out
    every move returns that status at once."""

    def __init__(self, controller: Controller, token: Token) -> None:
        self.controller = controller
        self.token = token

    def _guarded(self, command: ArmCommandName, move: Callable[[], ArmResult]) -> ArmResult:
        started = time.monotonic()
        if self.token.ended():
            return self.controller.result(command, self.token.status or "failed", self.token.reason, started)
        try:
            return move()
        except ArmError as e:
            return self.controller.result(command, "failed", str(e), started)

    def move_joints(self, q_rad: np.ndarray, speed: float) -> ArmResult:
        return self._guarded("move_joints", lambda: self.controller.move_joints(self.token, q_rad, speed))

    def move_pose(self, T_base_flange: np.ndarray, speed: float) -> ArmResult:
        return self._guarded("move_pose", lambda: self.controller.move_pose(self.token, T_base_flange, speed))

    @property
    def safety(self) -> Safety:
        """The service's rules, for compound commands to check their poses before the first motion."""
        return self.controller.safety

    def T_base_flange(self) -> np.ndarray:
        from sofia_schemas.kinematics import panda_fk

        return panda_fk(self.q(), check_limits=False)

    def q(self) -> np.ndarray:
        q = self.controller.link.mean_q(0.05)
        if q is None:
            raise NotReady("no robot state received yet")
        return q

    def wait_still(self, timeout_s: float) -> bool:
        return self.controller.wait_still(self.token, timeout_s)

    def stamp_ns(self) -> int:
        s = self.controller.link.latest
        if s is None:
            raise NotReady("no robot state received yet")
        return s.stamp_ns


class Commands:
    """Runs :class:`ArmCommand` s on a :class:`Controller`."""

    def __init__(self, controller: Controller, session: zenoh.Session | None, keys: Keys) -> None:
        self.controller = controller
        self.session = session
        self.keys = keys

    def check(self, cmd: ArmCommand) -> None:
        """Refuse a command that cannot run now (ArmError naming why), without moving anything."""
        c = self.controller
        if cmd.command in ("stop", "recover"):
            return
        if cmd.command in COMPOUND:
            load_compound(cmd.command)
        c.ready()
        s = c.link.latest
        if s is None:
            raise NotReady("no robot state received yet")
        if cmd.command == "move_joints":
            c.safety.check_joint_target(np.asarray(cmd.q), s.q)
        elif cmd.command == "home":
            c.safety.check_joint_target(np.array(c.config.home_q), s.q, "home target")
        elif cmd.command == "move_pose":
            c.safety.check_pose_target(self.target_pose(cmd), s.q, np.array(c.config.home_q))
        elif cmd.command == "pick_place" and cmd.target is not None:
            from .pick_place import check_pick_place  # the same checks it runs before its first motion

            check_pick_place(cmd, cmd.target, c.safety, s.q)
        elif cmd.command == "sort_colours":
            from .sort import check_sort

            check_sort(cmd, c.safety, s.q)
        elif cmd.command == "calibrate":
            from .autocal_options import AutocalOptions

            try:
                opts = AutocalOptions.from_dict(cmd.calibrate, cmd.speed)
            except (TypeError, ValueError) as e:
                raise TargetRefused(f"calibrate options: {e}") from None
            if opts.blob is not None and opts.setup == "eye-in-hand":  # eye-to-hand: on the flange
                c.safety.check_look_target(np.array(opts.blob), "calibrate blob")

    @staticmethod
    def target_pose(cmd: ArmCommand) -> np.ndarray:
        assert cmd.position is not None and cmd.quaternion_xyzw is not None
        return make_transform(np.array(cmd.position), np.array(cmd.quaternion_xyzw))

    def stop(self, cmd: ArmCommand) -> ArmResult:
        """Stop now: cancel the running command and bring the robot to rest."""
        started = time.monotonic()
        c = self.controller
        c.cancel_current("stopped", "stopped by a stop command")
        c.halt()
        still = c.wait_still(None, min(cmd.timeout_s, HALT_TIMEOUT_S))
        if still:
            result = c.result("stop", "done", "the arm is at rest", started)
        else:
            result = c.result("stop", "failed", "the arm did not come to rest", started)
        c.last_result = result
        return result

    def run(self, cmd: ArmCommand, token: Token) -> ArmResult:
        """Run a checked command under ``token`` (begun by the caller); errors raise ArmError."""
        c = self.controller
        try:
            if cmd.command == "move_joints":
                result = c.move_joints(token, np.asarray(cmd.q), cmd.speed)
            elif cmd.command == "home":
                result = c.move_joints(token, np.array(c.config.home_q), cmd.speed, "home")
            elif cmd.command == "move_pose":
                result = c.move_pose(token, self.target_pose(cmd), cmd.speed)
            elif cmd.command == "recover":
                result = self.recover(token)
            else:
                func = load_compound(cmd.command)
                result = func(cmd, CommandMotion(c, token), self.session, self.keys)
        except BaseException:
            c.finish(token, c.result(cmd.command, "failed", "raised", token.started))
            raise
        c.finish(token, result)
        return result

    def recover(self, token: Token) -> ArmResult:
        """Reconnect if needed, run the robot's automatic error recovery, clear the errors."""
        c, link = self.controller, self.controller.link
        started = time.monotonic()
        if not link.connected.wait(min(token.timeout_s, RECOVER_TIMEOUT_S)):
            return c.result(
                "recover", "failed", link.error or f"the robot at {link.host} does not answer", started
            )
        robot = link.robot
        try:
            assert robot is not None
            ok = robot.recover_from_errors()
        except Exception as e:
            return c.result(
                "recover", "failed", f"automatic error recovery failed: {type(e).__name__}: {e}", started
            )
        link.error = None
        sample = link.wait_sample(time.time_ns(), 2.0)
        if not ok or sample is None or sample.errors:
            errors: Any = sample.errors if sample is not None else "no state"
            return c.result("recover", "failed", f"the robot still reports errors: {errors}", started)
        return c.result("recover", "done", "recovered: no errors", started)
