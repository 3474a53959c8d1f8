"""A motion during which the robot's state stops advancing while the link stays up (seen in the
simulated cell after a host stall) is stopped instead of hanging until the command's time-out. A
stalled simulator is libfranka's own UDP time-out instead (a failed move, as in `test_arm_service`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import pytest
import sofia_arm.controller as controller
from sofia_arm.command_token import Token
from sofia_arm.config import ArmConfig
from sofia_arm.controller import Controller


@dataclass
class StuckRobot:
    """A franky Robot whose motion never ends until stopped."""

    stopped: bool = False
    current_control_signal_type: None = None

    def move(self, motion: object, asynchronous: bool) -> None:
        pass

    def join_motion(self, timeout: float) -> bool:
        time.sleep(timeout)
        return self.stopped

    def stop(self) -> None:
        self.stopped = True


@dataclass
class FrozenLink:
    """A RobotLink whose latest state never advances; after a stop it answers (``answers``) or not."""

    answers: bool
    latest: SimpleNamespace = field(default_factory=lambda: SimpleNamespace(robot_time_ns=1))
    lost_reason: str | None = None

    def wait_sample(self, after_ns: int, timeout: float) -> SimpleNamespace | None:
        return self.latest if self.answers else None

    def lost(self, reason: str) -> None:
        self.lost_reason = reason


@pytest.mark.parametrize("answers", [True, False])
def test_a_motion_without_robot_states_is_stopped(monkeypatch: pytest.MonkeyPatch, answers: bool) -> None:
    monkeypatch.setattr(controller, "STATE_SILENCE_S", 0.3)
    monkeypatch.setattr(controller, "HALT_TIMEOUT_S", 0.1)
    link, robot = FrozenLink(answers), StuckRobot()
    ctl = Controller(link, ArmConfig(), lambda: None)  # type: ignore[arg-type]
    t0 = time.monotonic()
    ended = ctl._run(Token("move_joints", 60.0), robot, object())  # type: ignore[arg-type]
    assert robot.stopped and time.monotonic() - t0 < 5.0
    if answers:  # the motion counts as ended: the caller measures where the arm is
        assert ended is None and link.lost_reason is None
    else:  # no state even after the stop: the connection is lost, with the reason
        assert ended is not None and ended[0] == "failed" and "no state" in ended[1]
        assert link.lost_reason == ended[1]
