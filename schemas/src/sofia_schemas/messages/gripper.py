"""Gripper commands, results and state."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Finite, Message

GripperAction = Literal["open", "close", "move", "grasp", "release", "stop", "torque", "reboot", "state"]


class GripperCommand(Message):
    """A command for the gripper service (query payload on ``gripper/command``)."""

    action: GripperAction
    opening_mm: Finite | None = None  # for move
    position_ticks: int | None = None  # for move, instead of opening_mm
    speed: Finite | None = Field(None, gt=0, le=1.0)  # fraction of the configured max velocity
    force_n: Finite | None = Field(None, ge=0)  # grasp force limit
    current_ma: Finite | None = Field(None, ge=0)  # grasp current limit, instead of force_n
    enable: bool | None = None  # for torque
    timeout_s: Finite = Field(5.0, gt=0, le=60)


class GripperState(Message):
    """State of the gripper, published at the state-loop rate."""

    stamp_ns: int
    connected: bool
    status: Literal["ok", "moving", "error", "disconnected"]
    position_ticks: int | None = None
    position_rad: float | None = None
    opening_mm: float | None = None
    velocity_rad_s: float | None = None
    current_ma: float | None = None
    force_n: float | None = None
    temperature_c: float | None = None
    voltage_v: float | None = None
    moving: bool = False
    torque_enabled: bool = False
    hardware_error: list[str] = []
    grasped: bool = False
    error: str | None = None
    watchdog_trips: int = 0  # Bus Watchdog trips cleared by the driver since it started


class GripperResult(Message):
    """Outcome of a gripper command."""

    action: GripperAction
    ok: bool
    reason: str  # "done", "timeout", "stalled", or what failed
    grasped: bool | None = None
    opening_mm: float | None = None
    duration_s: float = 0.0
    state: GripperState | None = None
