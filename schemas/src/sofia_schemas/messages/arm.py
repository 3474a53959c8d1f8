"""Arm commands, results and state (``sofia/{robot}/arm/...``).

Poses are of the flange (``panda_link8``) in the robot base frame (``panda_link0``), metres,
quaternions x y z w; joint positions are radians, joints 1-7.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, model_validator

from .base import Finite, Message, Quat, UnitQuat, Vec3
from .pick import PickTarget

ArmCommandName = Literal[
    "move_joints", "move_pose", "home", "stop", "recover", "pick_place", "calibrate", "sort_colours"
]
ArmStatus = Literal["done", "stopped", "preempted", "failed", "timeout"]
ArmMode = Literal["idle", "moving", "error", "disconnected", "stopping"]
JOINTS = 7


class ArmCommand(Message):
    """A command for the arm service (query payload on ``arm/command``).

    - ``move_joints``: ``q`` (7 joint positions, rad);
    - ``move_pose``: ``position`` + ``quaternion_xyzw`` of the flange in the base frame;
    - ``home``, ``stop``, ``recover``: no arguments;
    - ``pick_place``: ``target`` (a :class:`PickTarget`; without it the latest one published on
      ``pick/target``) and where to place it: ``place_position`` (+ optional
      ``place_quaternion_xyzw``) of the flange, or ``place_object``, the point on the surface
      under the object's centre where the object should end up (base frame, m);
    - ``calibrate``: options in ``calibrate`` (free dict, read by the autonomous calibration);
    - ``sort_colours``: ``places_by_colour``, colour name -> the point on the surface where
      objects of that colour should end up (base frame, m); every object of those colours is
      picked and placed, colour by colour in the mapping's order.

    ``speed`` is relative to the robot's maximum velocity, acceleration and jerk, capped by the
    service's configured limits; ``timeout_s`` bounds the whole command.
    """

    command: ArmCommandName
    q: tuple[Finite, Finite, Finite, Finite, Finite, Finite, Finite] | None = None
    position: Vec3 | None = None
    quaternion_xyzw: UnitQuat | None = None
    speed: Finite = Field(0.1, gt=0.0, le=1.0)
    timeout_s: Finite = Field(30.0, gt=0.0, le=3600.0)
    target: PickTarget | None = None
    place_position: Vec3 | None = None
    place_quaternion_xyzw: UnitQuat | None = None
    place_object: Vec3 | None = None
    places_by_colour: dict[str, Vec3] = {}
    calibrate: dict[str, Any] = {}

    @model_validator(mode="after")
    def _arguments(self) -> ArmCommand:
        if self.command == "move_joints" and self.q is None:
            raise ValueError("move_joints needs q: 7 joint positions in radians")
        if self.command == "move_pose" and (self.position is None or self.quaternion_xyzw is None):
            raise ValueError("move_pose needs position (x y z, m) and quaternion_xyzw of the flange")
        if self.command == "pick_place" and (self.place_position is None) == (self.place_object is None):
            raise ValueError(
                "pick_place needs one of place_position (x y z, m) of the flange or place_object "
                "(x y z, m: the point on the surface under the object's centre where it should end up)"
            )
        if self.command == "sort_colours" and not self.places_by_colour:
            raise ValueError("sort_colours needs places_by_colour: colour name -> place (x y z, m)")
        return self


class ArmPhase(Message):
    """One step of a compound command (pick and place, calibration). A calibration view that gave no
    sample is ``failed`` and named ``visit N`` (:data:`VIEW_WITHOUT_SAMPLE`): the next view is tried."""

    name: str
    status: ArmStatus
    reason: str = ""
    duration_s: float = 0.0

    def line(self) -> str:
        """One progress line for people: ``ok``, ``skip`` (a view without a sample) or ``FAIL``."""
        skipped = self.name.startswith(VIEW_WITHOUT_SAMPLE)
        mark = "ok  " if self.status == "done" else "skip" if skipped else "FAIL"
        return f"{mark} {self.name}: {self.reason}"


VIEW_WITHOUT_SAMPLE = "visit"  # name of a calibration view that gave no sample, before its number


class ArmResult(Message):
    """Outcome of an arm command, with the measured pose at its end.

    ``status``: ``done``; ``stopped`` (a ``stop`` command or the robot stopped it); ``preempted``
    (a newer command took over); ``failed`` (``reason`` says why: refused target, robot error,
    lost connection); ``timeout`` (``timeout_s`` elapsed). ``ok`` is True only for ``done``.
    """

    ok: bool
    command: ArmCommandName
    status: ArmStatus
    reason: str = ""
    q: tuple[float, ...] | None = None  # measured joint positions at the end, rad
    position: Vec3 | None = None  # measured flange position at the end, base frame, m
    quaternion_xyzw: Quat | None = None  # measured flange orientation at the end
    duration_s: float = 0.0
    phases: list[ArmPhase] = []
    details: dict[str, Any] = {}  # command-specific results (e.g. the calibration result)


class ArmState(Message):
    """State of the arm, published on ``arm/state`` (a few times per second and on changes)."""

    stamp_ns: int
    connected: bool
    mode: ArmMode
    robot_mode: str = ""  # the robot's own mode (e.g. "Move", "Idle", "Reflex", "UserStopped")
    moving: bool = False
    errors: list[str] = []
    q: tuple[float, ...] | None = None
    position: Vec3 | None = None
    quaternion_xyzw: Quat | None = None
    current_command: ArmCommandName | None = None
    last_command: ArmCommandName | None = None
    last_result: ArmResult | None = None
    state_rate_hz: float = 0.0  # robot states read per second
    robot_rate_hz: float = 0.0  # robot states produced per second (1 kHz on a real robot)
    publish_rate_hz: float = 0.0  # flange poses published per second
