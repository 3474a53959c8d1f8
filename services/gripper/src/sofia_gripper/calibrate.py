"""``sofia gripper calibrate``: record the open and closed motor positions into a config file.

With the torque off, the user moves the fingers by hand to fully open, then fully closed; the
present position is read at each step and written as ``open_ticks`` / ``closed_ticks``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from .bus import DxlBus
from .config import GripperConfig, save_config
from .control_table import MODEL
from .errors import ConfigError, WrongModel


def calibrate(
    config: GripperConfig, out: Path, ask: Callable[[str], str] = input, say: Callable[[str], None] = print
) -> GripperConfig:
    """Prompt, read the two positions, save and return the new config."""
    bus = DxlBus(config.port, config.baud, config.protocol, config.dxl_id)
    bus.open()
    try:
        model = bus.ping()
        if model != MODEL[config.protocol]:
            raise WrongModel(config.dxl_id, model, MODEL[config.protocol])
        if config.protocol == 2:
            bus.write("bus_watchdog", 0)
        bus.write("torque_enable", 0)
        say("Torque is OFF: the fingers move freely.")
        ask("Move the fingers by hand to fully OPEN, then press Enter: ")
        open_ticks = bus.read("present_position")
        say(f"open position: {open_ticks} ticks")
        ask("Move the fingers by hand to fully CLOSED, then press Enter: ")
        closed_ticks = bus.read("present_position")
        say(f"closed position: {closed_ticks} ticks")
    finally:
        bus.close()
    if abs(closed_ticks - open_ticks) < 50:
        raise ConfigError(
            f"open {open_ticks} and closed {closed_ticks} ticks are too close: did the fingers move?"
        )
    if closed_ticks < open_ticks:
        fix = (
            "set the servo's Drive Mode to reverse (bit 0) or mount the horn the other way"
            if config.protocol == 2
            else "mount the horn the other way (Protocol 1.0 firmware has no Drive Mode)"
        )
        raise ConfigError(
            f"closing decreases the motor position ({open_ticks} -> {closed_ticks} ticks); {fix}, "
            "then calibrate again"
        )
    data = config.model_dump()
    data.update(open_ticks=open_ticks, closed_ticks=closed_ticks)
    new = GripperConfig.model_validate(data)
    save_config(new, out)
    kin = new.kinematics()
    say(
        f"saved {out}: open {open_ticks} ticks ({float(kin.opening(open_ticks)):.1f} mm), "
        f"closed {closed_ticks} ticks ({float(kin.opening(closed_ticks)):.1f} mm)"
    )
    sys.stdout.flush()
    return new
