"""What the emulated MX-64 accepts in a Write, per the ROBOTIS e-Manual.

Each rule names its e-Manual section. :func:`check_write` returns the status error of a Write
(Protocol 2.0 error number, Protocol 1.0 error bits), 0 when it is accepted.

- Protocol 2.0 "Status Packet": Data Length Error when fewer bytes are written than the item
  holds (e.g. 2 bytes into the 4-byte Goal Position); Access Error for read-only items and for
  EEPROM items while Torque Enable is 1 ("Control Table Description", MX-64(2.0)).
- Min/Max Position Limit(48, 52): used in Position Control Mode (3) only; Extended Position (4)
  and Current-based Position (5) take goals in -1,048,575 .. 1,048,575 (256 turns each way).
- Goal Current(102): within -Current Limit(38) .. Current Limit(38).
- Bus Watchdog(98): after a trip (-1) the goal values (Goal PWM, Goal Current, Goal Velocity,
  Goal Position) are read-only and a write gets a Data Range Error until 0 is written.
- Protocol 1.0 (MX-64AR/AT): Goal Position outside CW/CCW Angle Limit(6, 8) in Joint Mode sets
  the Angle Limit Error bit; other refusals set the Range Error bit.
"""

from __future__ import annotations

from collections.abc import Callable

from dynamixel_sdk.protocol1_packet_handler import ERRBIT_ANGLE

from . import packets as pk
from .control_table import (
    OPERATING_MODE_CURRENT_BASED_POSITION,
    WATCHDOG_TRIPPED,
    Field,
    Protocol,
    decode_int,
)

OPERATING_MODE_POSITION = 3
OPERATING_MODE_EXTENDED_POSITION = 4
MULTI_TURN_GOAL_LIMIT = 1_048_575  # Goal Position range in operating modes 4 and 5
GOAL_ITEMS = {"goal_pwm", "goal_current", "goal_velocity", "goal_position"}


def position_limited(protocol: Protocol, get: Callable[[str], int]) -> bool:
    """Whether Min/Max Position (P2) or CW/CCW Angle (P1) Limits bound the Goal Position now."""
    if protocol == 2:
        return get("operating_mode") == OPERATING_MODE_POSITION
    return not (get("min_position_limit") == get("max_position_limit") == 4095)  # multi-turn mode


def check_write(
    protocol: Protocol,
    touched: list[tuple[str, Field]],
    new: bytearray,
    get: Callable[[str], int],
    partial: bool = False,
) -> int:
    """Status error of a write over the items ``touched``; ``new`` is the whole control table
    with the write applied, ``get`` reads the table as it is before the write, ``partial`` says
    the write covers only part of an item (:func:`partial_item`)."""
    p2 = protocol == 2
    refused = pk.ERR_ACCESS if p2 else pk.ERRBIT1_RANGE
    if not touched or any(not f.writable for _, f in touched):
        return refused
    torque_on = get("torque_enable") if p2 else get("lock")
    if any(f.eeprom for _, f in touched) and torque_on:
        return refused
    if p2 and partial:
        return pk.ERR_DATA_LENGTH
    names = {name for name, _ in touched}
    if p2 and get("bus_watchdog") == WATCHDOG_TRIPPED and names & GOAL_ITEMS:
        return pk.ERR_DATA_RANGE
    if "goal_position" in names:
        f = dict(touched)["goal_position"]
        goal = decode_int(new, f.address, f)
        if position_limited(protocol, get):
            if not get("min_position_limit") <= goal <= get("max_position_limit"):
                return pk.ERR_DATA_LIMIT if p2 else ERRBIT_ANGLE
        elif p2 and get("operating_mode") in (
            OPERATING_MODE_EXTENDED_POSITION,
            OPERATING_MODE_CURRENT_BASED_POSITION,
        ):
            if abs(goal) > MULTI_TURN_GOAL_LIMIT:
                return pk.ERR_DATA_LIMIT
    if p2 and "goal_current" in names:
        f = dict(touched)["goal_current"]
        if abs(decode_int(new, f.address, f)) > get("current_limit"):
            return pk.ERR_DATA_LIMIT
    if "torque_enable" in names and new[dict(touched)["torque_enable"].address] > 1:
        return pk.ERR_DATA_RANGE if p2 else pk.ERRBIT1_RANGE
    return 0


def partial_item(touched: list[tuple[str, Field]], address: int, length: int) -> bool:
    """Whether a write of ``length`` bytes at ``address`` covers only part of an item."""
    return any(f.address < address or f.address + f.size > address + length for _, f in touched)
