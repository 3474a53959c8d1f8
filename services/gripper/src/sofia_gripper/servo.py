"""The servo's settings: bringing it into service, its goal writes, and its Bus Watchdog.

:meth:`Servo.configure` runs at every (re)connect. EEPROM items (Return Delay Time, Operating
Mode) are written only when they differ from what the servo holds: EEPROM has a limited number of
write cycles. In current-based position mode (5) the servo ignores Min/Max Position Limit
(e-Manual, "Min/Max Position Limit(48, 52)"), so the clamp of :meth:`Servo.set_goal` to the
calibrated open/closed positions is the stop; Protocol 1.0 Joint Mode applies CW/CCW Angle Limit,
which must contain the calibrated range.

:meth:`Servo.recover_watchdog` handles a Bus Watchdog trip (e-Manual, "Bus Watchdog(98)"): when
the host is silent for longer than the watchdog, the servo stops, reads -1 at address 98 and
refuses writes of the goal values with a Data Range Error until 0 is written. The servo is
cleared and re-armed, and the running command sends its goals again.
"""

from __future__ import annotations

import logging

from dynamixel_sdk.protocol2_packet_handler import ERRNUM_DATA_RANGE

from .bus import DxlBus
from .config import GripperConfig
from .control_table import (
    OPERATING_MODE_CURRENT_BASED_POSITION,
    STALL_CURRENT_MA,
    UNITS,
    WATCHDOG_TRIPPED,
    WATCHDOG_UNIT_MS,
)
from .errors import GripperError, ServoRefused

log = logging.getLogger(__name__)


class Servo:
    """The MX-64 behind ``bus`` as ``config`` wants it; ``counters["watchdog_trips"]`` counts trips."""

    def __init__(self, bus: DxlBus, config: GripperConfig, counters: dict[str, int]) -> None:
        self.bus, self.config, self.counters = bus, config, counters
        self.units = UNITS[config.protocol]
        self.limits = (config.open_ticks, config.closed_ticks)  # goal clamp, ticks (open, closed)
        self.current_limit_ma = config.max_current_ma

    def write_if_changed(self, name: str, value: int) -> bool:
        """Write ``name`` only if the servo holds another value; True when written."""
        if self.bus.read(name) == value:
            return False
        self.bus.write(name, value)
        log.info("servo %s set to %d", name, value)
        return True

    def configure(self) -> None:
        """Read limits, set the operating mode and currents, arm the watchdog, torque on."""
        c, b, p2 = self.config, self.bus, self.config.protocol == 2
        if p2:
            b.write("bus_watchdog", 0)  # clears a tripped watchdog
            mode = b.read("operating_mode") if b.read("torque_enable") == 1 else None
            resume = mode == OPERATING_MODE_CURRENT_BASED_POSITION
        else:
            resume = b.read("torque_enable") == 1 and b.read("torque_limit") > 0
        if not resume:
            b.write("torque_enable", 0)
            self.write_if_changed("return_delay_time", 0)
            if p2:
                self.write_if_changed("operating_mode", OPERATING_MODE_CURRENT_BASED_POSITION)
        if not p2:
            low, high = b.read("min_position_limit"), b.read("max_position_limit")
            self.limits = (max(low, c.open_ticks), min(high, c.closed_ticks))
            if self.limits[0] >= self.limits[1]:
                raise GripperError(
                    f"servo CW/CCW Angle Limit [{low}, {high}] excludes the calibrated range "
                    f"{c.open_ticks}..{c.closed_ticks}: widen the limits (EEPROM, torque off)"
                )
        servo_max = b.read("current_limit") * self.units.current_ma if p2 else STALL_CURRENT_MA
        self.current_limit_ma = min(c.max_current_ma, servo_max)
        if not resume:
            self.set_current(c.move_current_ma)
            self.set_speed(1.0)
            b.write("goal_position", b.read("present_position"))
            b.write("torque_enable", 1)
        self.arm_watchdog()

    def write_goal(self, name: str, value: int) -> None:
        """Write a goal value; a refusal from a tripped Bus Watchdog is cleared and retried once."""
        try:
            self.bus.write(name, value)
        except ServoRefused as e:
            if not (e.error == ERRNUM_DATA_RANGE and self.recover_watchdog()):
                raise
            self.bus.write(name, value)

    def set_current(self, current_ma: float) -> None:
        """Goal Current (2.0) or Torque Limit (1.0) for ``current_ma``, capped at the current limit."""
        current_ma = min(current_ma, self.current_limit_ma)
        if self.config.protocol == 2:
            self.write_goal("goal_current", round(current_ma / self.units.current_ma))
        else:
            self.bus.write("torque_limit", round(current_ma / STALL_CURRENT_MA * 1023))

    def set_speed(self, fraction: float) -> None:
        """Profile Velocity at ``fraction`` of the configured maximum."""
        units = round(self.config.max_velocity_rpm * fraction / self.units.velocity_rpm)
        self.bus.write("profile_velocity", max(1, units))

    def set_goal(self, ticks: float) -> int:
        """Goal Position clamped to the calibrated open..closed range (the servo applies no
        position limit in current-based position mode); returns the goal written, ticks."""
        goal = round(min(max(ticks, self.limits[0]), self.limits[1]))
        self.write_goal("goal_position", goal)
        return goal

    def arm_watchdog(self) -> None:
        if self.config.protocol == 2 and self.config.watchdog_ms:
            self.bus.write("bus_watchdog", max(1, self.config.watchdog_ms // WATCHDOG_UNIT_MS))

    def recover_watchdog(self) -> bool:
        """If the Bus Watchdog tripped: count and report it, clear and re-arm it; True if it had."""
        if self.config.protocol != 2 or not self.config.watchdog_ms:
            return False
        if self.bus.read("bus_watchdog") != WATCHDOG_TRIPPED:
            return False
        self.counters["watchdog_trips"] += 1
        log.warning(
            "bus watchdog tripped (the host sent nothing for over %d ms): servo stopped; clearing and re-arming",
            self.config.watchdog_ms,
        )
        self.bus.write("bus_watchdog", 0)
        self.arm_watchdog()
        return True
