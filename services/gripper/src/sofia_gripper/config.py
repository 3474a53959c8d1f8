"""Gripper configuration: serial line, servo, geometry, calibration, limits (YAML file)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from .errors import ConfigError
from .kinematics import GripperKinematics, OpeningTable, SliderCrank

DEFAULT_CALIBRATION = [[4.0, 100.0], [10.0, 80.0], [16.0, 58.0], [22.0, 36.0], [28.0, 16.0], [34.0, 0.0]]


class GripperConfig(BaseModel):
    """Everything the driver needs. Positions in motor ticks (4096 per turn), lengths in mm."""

    model_config = ConfigDict(extra="forbid")

    port: str = "/dev/ttyUSB0"
    baud: int = Field(default=57600, gt=0)
    dxl_id: int = Field(default=1, ge=0, le=252)
    protocol: Literal[1, 2] = 2
    # slider-crank and calibration
    crank_radius_mm: float = Field(default=20.0, gt=0)
    rod_length_mm: float = Field(default=50.0, gt=0)
    offset_mm: float = 5.0
    crank_zero_ticks: int = 1024
    calibration: list[tuple[float, float]] = Field(
        default_factory=lambda: [(r[0], r[1]) for r in DEFAULT_CALIBRATION]
    )
    open_ticks: int = Field(default=1433, ge=0, le=4095)
    closed_ticks: int = Field(default=2519, ge=0, le=4095)
    # limits and behaviour
    max_current_ma: float = Field(default=2000.0, gt=0)  # never commanded above this
    move_current_ma: float = Field(default=600.0, gt=0)  # open / close / move
    grasp_current_ma: float = Field(default=500.0, gt=0)  # grasp default
    force_per_amp_n: float = Field(default=25.0, gt=0)  # finger force per motor ampere (estimate)
    max_velocity_rpm: float = Field(default=40.0, gt=0)
    max_temperature_c: float = Field(default=70.0, gt=0)  # driver stops above this (servo shuts down at 80)
    watchdog_ms: int = Field(default=200, ge=0, le=2540)  # servo Bus Watchdog; 0 disables
    state_rate_hz: float = Field(default=100.0, gt=0, le=2000)
    position_tolerance_ticks: int = Field(default=15, ge=1)
    stall_time_s: float = Field(default=0.08, gt=0)
    reconnect_period_s: float = Field(default=0.5, gt=0)
    # added to dynamixel_sdk's wait for each status packet; `serve --emulate` sets 200 ms (the
    # emulated servo is a process on the same, possibly loaded host; a real servo answers in < 1 ms)
    reply_margin_ms: float = Field(default=0.0, ge=0, le=1000)

    @model_validator(mode="after")
    def _check(self) -> GripperConfig:
        if self.open_ticks == self.closed_ticks:
            raise ValueError(f"open_ticks and closed_ticks are both {self.open_ticks}")
        if self.open_ticks > self.closed_ticks:
            raise ValueError(
                f"closing must increase the motor position: open_ticks {self.open_ticks} > "
                f"closed_ticks {self.closed_ticks}"
            )
        for name in ("move_current_ma", "grasp_current_ma"):
            if getattr(self, name) > self.max_current_ma:
                raise ValueError(
                    f"{name} {getattr(self, name)} mA exceeds max_current_ma {self.max_current_ma}"
                )
        self.kinematics()  # validates geometry and table
        return self

    def kinematics(self) -> GripperKinematics:
        crank = SliderCrank(self.crank_radius_mm, self.rod_length_mm, self.offset_mm)
        return GripperKinematics(crank, OpeningTable(self.calibration), self.crank_zero_ticks)


def load_config(path: str | Path) -> GripperConfig:
    """Read a YAML config file; a missing file or bad value raises :class:`ConfigError`."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"gripper config file {str(p)!r} does not exist")
    try:
        data = yaml.safe_load(p.read_text()) or {}
        return GripperConfig.model_validate(data)
    except (yaml.YAMLError, ValidationError) as e:
        raise ConfigError(f"gripper config {str(p)!r} is invalid: {e}") from e


def save_config(config: GripperConfig, path: str | Path) -> None:
    data = config.model_dump()
    data["calibration"] = [list(r) for r in config.calibration]
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False))
