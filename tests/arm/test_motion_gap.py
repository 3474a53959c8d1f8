"""Back-to-back motions (a correction's approach, then the correction) start ``MOTION_GAP_S`` of the
robot's clock apart: libfranka keeps sending a finished motion's last command until it sees the robot
idle, and a Move that reached franky-sim together with such a command was ended at once while
libfranka waited forever for its reply (the simulated cell's stall)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import sofia_arm.controller as controller
from sofia_arm.command_token import Token
from sofia_arm.config import ArmConfig
from sofia_arm.controller import Controller


@dataclass
class Sample:
    robot_time_ns: int


class ClockLink:
    """A RobotLink whose robot clock runs at a tenth of wall time (a slow simulator)."""

    def __init__(self) -> None:
        self.t0 = time.monotonic_ns()

    @property
    def latest(self) -> Sample:
        return Sample((time.monotonic_ns() - self.t0) // 10)


@dataclass
class QuickRobot:
    """A franky Robot whose motions end at once; records the robot time at each start."""

    link: ClockLink
    starts_ns: list[int] = field(default_factory=list)
    current_control_signal_type: None = None

    def move(self, motion: object, asynchronous: bool) -> None:
        self.starts_ns.append(self.link.latest.robot_time_ns)

    def join_motion(self, timeout: float) -> bool:
        return True


def test_back_to_back_motions_start_a_gap_of_robot_time_apart() -> None:
    link = ClockLink()
    robot = QuickRobot(link)
    ctl = Controller(link, ArmConfig(), lambda: None)  # type: ignore[arg-type]
    token = Token("move_joints", 60.0)
    for _ in range(3):
        assert ctl._run(token, robot, object()) is None  # type: ignore[arg-type]
    gaps_s = [(b - a) / 1e9 for a, b in zip(robot.starts_ns, robot.starts_ns[1:], strict=False)]
    assert len(gaps_s) == 2 and min(gaps_s) >= controller.MOTION_GAP_S, gaps_s
    assert max(gaps_s) < 10 * controller.MOTION_GAP_S, gaps_s  # a gap, not a stall
