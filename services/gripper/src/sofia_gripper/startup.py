"""Bringing the servo into service, and keeping its Bus Watchdog armed.

:func:`configure` runs at every (re)connect. EEPROM items (Return Delay Time, Operating Mode)
are written only when they differ from what the servo holds: EEPROM has a limited number of
write cycles. In current-based position mode (5) the servo ignores Min/Max Position Limit
(e-Manual, "Min/Max Position Limit(48, 52)"), so the driver's own clamp to the calibrated
open/closed positions is the stop; Protocol 1.0 Joint Mode applies CW/CCW Angle Limit, which
must contain the calibrated range.

:func:`recover_watchdog` handles a Bus Watchdog trip (e-Manual, "Bus Watchdog(98)"): when the
host is silent for longer than the watchdog, the servo stops, reads -1 at address 98 and refuses
writes of the goal values with a Data Range Error until 0 is written. The driver clears it,
re-arms it and lets the running command send its goals again.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from . import packets as pk
from .control_table import (
    OPERATING_MODE_CURRENT_BASED_POSITION,
    STALL_CURRENT_MA,
    WATCHDOG_TRIPPED,
    WATCHDOG_UNIT_MS,
)
from .errors import GripperError, ServoRefused

if TYPE_CHECKING:
    from .driver import Gripper

log = logging.getLogger(__name__)


def write_if_changed(g: Gripper, name: str, value: int) -> bool:
    """Write ``name`` only if the servo holds another value; True when written."""
    if g.bus.read(name) == value:
        return False
    g.bus.write(name, value)
    log.info("servo %s set to %d", name, value)
    return True


def configure(g: Gripper) -> None:
    """Read limits, set the operating mode and currents, arm the watchdog, torque on."""
    c, b, p2 = g.config, g.bus, g.config.protocol == 2
    if p2:
        b.write("bus_watchdog", 0)  # clears a tripped watchdog
        resume = (
            b.read("torque_enable") == 1 and b.read("operating_mode") == OPERATING_MODE_CURRENT_BASED_POSITION
        )
    else:
        resume = b.read("torque_enable") == 1 and b.read("torque_limit") > 0
    if not resume:
        b.write("torque_enable", 0)
        write_if_changed(g, "return_delay_time", 0)
        if p2:
            write_if_changed(g, "operating_mode", OPERATING_MODE_CURRENT_BASED_POSITION)
    if p2:
        g.limits = (c.open_ticks, c.closed_ticks)
    else:
        low, high = b.read("min_position_limit"), b.read("max_position_limit")
        g.limits = (max(low, c.open_ticks), min(high, c.closed_ticks))
        if g.limits[0] >= g.limits[1]:
            raise GripperError(
                f"servo CW/CCW Angle Limit [{low}, {high}] excludes the calibrated range "
                f"{c.open_ticks}..{c.closed_ticks}: widen the limits (EEPROM, torque off)"
            )
    servo_max = b.read("current_limit") * g.units.current_ma if p2 else STALL_CURRENT_MA
    g.current_limit_ma = min(c.max_current_ma, servo_max)
    if not resume:
        g.set_current(c.move_current_ma)
        g.set_speed(1.0)
        b.write("goal_position", b.read("present_position"))
        b.write("torque_enable", 1)
    arm_watchdog(g)
    g.torque, g.hw_error, g.overheated = True, [], False


def arm_watchdog(g: Gripper) -> None:
    if g.config.protocol == 2 and g.config.watchdog_ms:
        g.bus.write("bus_watchdog", max(1, g.config.watchdog_ms // WATCHDOG_UNIT_MS))


def recover_watchdog(g: Gripper) -> bool:
    """If the Bus Watchdog tripped: count and report it, clear and re-arm it; True if it had."""
    if g.config.protocol != 2 or not g.config.watchdog_ms:
        return False
    if g.bus.read("bus_watchdog") != WATCHDOG_TRIPPED:
        return False
    g.counters["watchdog_trips"] += 1
    log.warning(
        "bus watchdog tripped (the host sent nothing for over %d ms): servo stopped; clearing and re-arming",
        g.config.watchdog_ms,
    )
    g.bus.write("bus_watchdog", 0)
    arm_watchdog(g)
    return True


def is_data_range(e: ServoRefused) -> bool:
    """Whether the servo refused with the Protocol 2.0 Data Range Error (a tripped watchdog)."""
    return e.error == pk.ERR_DATA_RANGE
