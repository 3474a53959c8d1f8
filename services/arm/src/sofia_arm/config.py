"""Arm configuration: robot model, dynamics limits, workspace box, joint margins, collision
thresholds, state rate, tolerances (YAML or JSON file, every field optional)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from sofia_schemas.files import FileContentError, load_json_or_yaml
from sofia_schemas.kinematics import RobotModel

from .errors import ConfigError

# The calibrator's and the detector's home: flange 0.55 m in front of the base, 0.62 m up, pointing down.
HOME_Q = (0.0, 0.0, 0.0, -1.5708, 0.0, 1.5708, 0.7854)


class ArmConfig(BaseModel):
    """Safety and behaviour of the arm service. Lengths in metres, angles in radians."""

    model_config = ConfigDict(extra="forbid")

    model: RobotModel = "panda"  # joint limits of the "panda" or the "fr3" (same kinematics)
    # relative to the robot's maximum velocity / acceleration / jerk; a command's speed is capped by these
    max_velocity: float = Field(0.1, gt=0.0, le=1.0)
    max_acceleration: float = Field(0.1, gt=0.0, le=1.0)
    max_jerk: float = Field(0.1, gt=0.0, le=1.0)
    stop_dynamics: float = Field(0.5, gt=0.0, le=1.0)  # relative dynamics of a stop (harder than moves)
    # flange positions (base frame) outside this box are refused
    workspace_min: tuple[float, float, float] = (0.15, -0.6, 0.05)
    workspace_max: tuple[float, float, float] = (0.85, 0.6, 0.9)
    joint_margin_rad: float = Field(0.05, ge=0.0, le=0.5)  # targets this close to a joint limit are refused
    # the tool on the flange: "sofia" (the gripper's fingers, a box from the flange to the fingertips
    # ``fingertip_offset_m`` along the flange z axis, ``finger_half_width_m`` either side along its x
    # and y axes) or "flange" (a bare flange: its origin only)
    tool: Literal["sofia", "flange"] = "sofia"
    fingertip_offset_m: float = Field(0.20, ge=0.0, le=0.6)
    finger_half_width_m: float = Field(0.055, ge=0.0, le=0.3)
    # the table/board top, a horizontal plane (base frame): the board file's surface_z when given,
    # else ``surface_z``; no point of the tool may come closer to it than ``surface_margin_m``
    surface_z: float = Field(0.0, ge=-1.0, le=1.0)
    board_file: Path | None = None
    surface_margin_m: float = Field(0.005, ge=0.0, le=0.2)
    gripper_max_opening_mm: float = Field(
        100.0, gt=0.0
    )  # picks the arm plans open the fingers at most this far
    # flange -> camera transform for the survey when no calibrator answers (YAML/JSON with ``matrix``,
    # as the detector's --transform file); the calibrator's latest result wins when there is one
    transform_file: Path | None = None
    # collision thresholds (the robot stops with a reflex above them)
    torque_threshold_nm: float = Field(20.0, gt=0.0)
    force_threshold_n: float = Field(30.0, gt=0.0)
    home_q: tuple[float, float, float, float, float, float, float] = HOME_Q
    state_rate_hz: float = Field(200.0, ge=100.0, le=1000.0)  # flange pose and joint state rate
    state_publish_hz: float = Field(10.0, gt=0.0, le=100.0)  # arm/state JSON rate
    # a motion is done when the measured flange pose is this close to the target (joint corrections
    # after the trajectory while it is farther than half of it, at most ``max_corrections``)
    position_tolerance_m: float = Field(0.001, gt=0.0)
    rotation_tolerance_deg: float = Field(0.1, gt=0.0)
    max_corrections: int = Field(4, ge=0, le=10)
    settle_timeout_s: float = Field(3.0, gt=0.0)
    still_speed_rad_s: float = Field(0.001, gt=0.0)  # mean joint speed below which the arm is still
    gripper_state_max_age_s: float = Field(2.0, gt=0.0)  # older gripper states are ignored
    reconnect_period_s: float = Field(1.0, gt=0.0)
    # "enforce": libfranka's control thread must get real-time priority (a PREEMPT_RT kernel and
    # rtprio for the user, as on the lab's control PC) or the connection fails; "ignore": it runs
    # without (franky-sim, development machines, CI)
    realtime: Literal["ignore", "enforce"] = "ignore"

    @model_validator(mode="after")
    def _check(self) -> ArmConfig:
        for axis, lo, hi in zip("xyz", self.workspace_min, self.workspace_max, strict=True):
            if lo >= hi:
                raise ValueError(f"workspace_min {axis} = {lo} m is not below workspace_max {axis} = {hi} m")
        return self


def load_config(path: str | Path | None, **overrides: object) -> ArmConfig:
    """The config in ``path`` (defaults when None) with ``overrides`` (None values ignored)."""
    data: dict[str, object] = {}
    if path is not None:
        try:
            loaded = load_json_or_yaml(path)
        except (OSError, FileContentError) as e:
            raise ConfigError(f"arm config {path}: {e}") from None
        if not isinstance(loaded, dict):
            raise ConfigError(f"arm config {path} must be a mapping of settings, got {type(loaded).__name__}")
        data.update(loaded)
    data.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return ArmConfig.model_validate(data)
    except ValidationError as e:
        raise ConfigError(f"arm config {path or '(defaults)'} is invalid: {e}") from None
