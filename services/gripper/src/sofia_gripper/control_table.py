"""MX-64 control table for Protocol 2.0 (MX-64(2.0) firmware) and Protocol 1.0, in one table.

Addresses and sizes from the ROBOTIS e-Manual (MX-64(2.0) and MX-64AR/AT control tables). Each
row names a quantity once; a protocol that lacks it has ``None`` in its column. Shared names
mean the same quantity (e.g. ``present_velocity`` is Present Speed (38) in Protocol 1.0), units
differ and are in :class:`Units`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from dynamixel_sdk.protocol1_packet_handler import ERRBIT_OVERHEAT, ERRBIT_OVERLOAD, ERRBIT_VOLTAGE
from dynamixel_sdk.protocol2_packet_handler import ERRBIT_ALERT

Protocol = Literal[1, 2]

MODEL_MX64_P2 = 311  # MX-64(2.0)
MODEL_MX64_P1 = 310  # MX-64AR/AT, Protocol 1.0 firmware
TICKS_PER_REV = 4096
OPERATING_MODE_CURRENT_BASED_POSITION = 5  # Protocol 2.0 Operating Mode (11)
WATCHDOG_UNIT_MS = 20  # Bus Watchdog (98) unit
WATCHDOG_TRIPPED = 0xFF  # Bus Watchdog reads -1 after it expired


@dataclass(frozen=True)
class Field:
    """One control-table item: byte ``address``, ``size`` in bytes, EEPROM or not, writable or not."""

    address: int
    size: int
    eeprom: bool = False
    writable: bool = True
    signed: bool = False


def _e(address: int, size: int, writable: bool = True) -> Field:
    return Field(address, size, eeprom=True, writable=writable)


def _r(address: int, size: int, signed: bool = False) -> Field:
    return Field(address, size, writable=False, signed=signed)


def _w(address: int, size: int, signed: bool = False) -> Field:
    return Field(address, size, signed=signed)


# name: (Protocol 2.0 field, Protocol 1.0 field)
TABLE: dict[str, tuple[Field | None, Field | None]] = {
    "model_number": (_e(0, 2, False), _e(0, 2, False)),
    "firmware_version": (_e(6, 1, False), _e(2, 1, False)),
    "id": (_e(7, 1), _e(3, 1)),
    "baud_rate": (_e(8, 1), _e(4, 1)),
    "return_delay_time": (_e(9, 1), _e(5, 1)),
    "drive_mode": (_e(10, 1), None),
    "operating_mode": (_e(11, 1), None),
    "homing_offset": (_e(20, 4), None),
    "moving_threshold": (_e(24, 4), None),
    "temperature_limit": (_e(31, 1), _e(11, 1)),
    "max_voltage_limit": (_e(32, 2), _e(13, 1)),
    "min_voltage_limit": (_e(34, 2), _e(12, 1)),
    "pwm_limit": (_e(36, 2), None),
    "current_limit": (_e(38, 2), None),
    "max_torque": (None, _e(14, 2)),
    "acceleration_limit": (_e(40, 4), None),
    "velocity_limit": (_e(44, 4), None),
    "max_position_limit": (_e(48, 4), _e(8, 2)),  # P1: CCW Angle Limit
    "min_position_limit": (_e(52, 4), _e(6, 2)),  # P1: CW Angle Limit
    "status_return_level": (_w(68, 1), _e(16, 1)),
    "alarm_led": (None, _e(17, 1)),
    "shutdown": (_e(63, 1), _e(18, 1)),
    "torque_enable": (_w(64, 1), _w(24, 1)),
    "led": (_w(65, 1), _w(25, 1)),
    "registered_instruction": (_r(69, 1), _r(44, 1)),
    "hardware_error_status": (_r(70, 1), None),
    "bus_watchdog": (_w(98, 1), None),
    "goal_pwm": (_w(100, 2, True), None),
    "goal_current": (_w(102, 2, True), None),
    "goal_velocity": (_w(104, 4, True), None),
    "profile_acceleration": (_w(108, 4), _w(73, 1)),  # P1: Goal Acceleration
    "profile_velocity": (_w(112, 4), _w(32, 2)),  # P1: Moving Speed
    "goal_position": (_w(116, 4, True), _w(30, 2)),
    "torque_limit": (None, _w(34, 2)),
    "realtime_tick": (_r(120, 2), _r(50, 2)),
    "moving": (_r(122, 1), _r(46, 1)),
    "moving_status": (_r(123, 1), None),
    "present_pwm": (_r(124, 2, True), None),
    "present_current": (_r(126, 2, True), _w(68, 2)),  # P1: Current, 2048 = 0 mA
    "present_velocity": (_r(128, 4, True), _r(38, 2)),  # P1: Present Speed, bit 10 = CW
    "present_position": (_r(132, 4, True), _r(36, 2)),
    "velocity_trajectory": (_r(136, 4, True), None),
    "position_trajectory": (_r(140, 4, True), None),
    "present_load": (None, _r(40, 2)),
    "present_input_voltage": (_r(144, 2), _r(42, 1)),
    "present_temperature": (_r(146, 1), _r(43, 1)),
    "lock": (None, _w(47, 1)),
    "punch": (None, _w(48, 2)),
    "torque_control_mode": (None, _w(70, 1)),
    "goal_torque": (None, _w(71, 2)),
}

# The block read once per state cycle: Moving (122) .. Present Temperature (146) in Protocol 2.0,
# Present Position (36) .. Current (68) in Protocol 1.0.
STATE_BLOCK: dict[Protocol, tuple[int, int]] = {2: (122, 25), 1: (36, 34)}

# Hardware Error Status (70) bits, Protocol 2.0; and the error byte of a Protocol 1.0 status packet.
HW_ERROR_BITS_P2 = {
    0: "input_voltage",
    2: "overheating",
    3: "motor_encoder",
    4: "electrical_shock",
    5: "overload",
}
STATUS_ERROR_BITS_P1 = {
    0: "input_voltage",
    1: "angle_limit",
    2: "overheating",
    3: "range",
    4: "checksum",
    5: "overload",
    6: "instruction",
}
HW_ERROR_MASK_P1 = ERRBIT_VOLTAGE | ERRBIT_OVERHEAT | ERRBIT_OVERLOAD  # the P1 bits that are hardware errors
ALERT_BIT_P2 = ERRBIT_ALERT


@dataclass(frozen=True)
class Units:
    """Unit of each quantity in one protocol."""

    current_ma: float  # mA per unit of present/goal current
    current_offset: int  # raw value meaning 0 mA (2048 in Protocol 1.0)
    velocity_rpm: float  # rpm per unit of present velocity / profile velocity
    direction_bit: int  # 0 in Protocol 2.0 (signed), 1024 in Protocol 1.0 (bit 10 = CW)
    voltage_v: float = 0.1
    position_bits: int = 32


UNITS: dict[Protocol, Units] = {
    2: Units(current_ma=3.36, current_offset=0, velocity_rpm=0.229, direction_bit=0),
    1: Units(current_ma=4.5, current_offset=2048, velocity_rpm=0.114, direction_bit=1024, position_bits=16),
}
MODEL: dict[Protocol, int] = {2: MODEL_MX64_P2, 1: MODEL_MX64_P1}
STALL_CURRENT_MA = 4100.0  # MX-64 stall current at 12 V; Protocol 1.0 Torque Limit 1023 = this


def fields(protocol: Protocol) -> dict[str, Field]:
    """The control table of one protocol: name -> :class:`Field`."""
    col = 0 if protocol == 2 else 1
    return {name: row[col] for name, row in TABLE.items() if row[col] is not None}  # type: ignore[misc]


def decode_int(data: bytes | bytearray | list[int], offset: int, field: Field) -> int:
    """Little-endian integer of ``field`` found at ``offset`` in ``data``."""
    return int.from_bytes(bytes(data[offset : offset + field.size]), "little", signed=field.signed)


def encode_int(value: int, field: Field) -> bytes:
    """``value`` as ``field.size`` little-endian bytes (negative values two's complement)."""
    return (value % (1 << (8 * field.size))).to_bytes(field.size, "little")


def hardware_error_words(protocol: Protocol, bits: int) -> list[str]:
    """Names of the set hardware-error bits (P2 Hardware Error Status, P1 status error byte)."""
    names = HW_ERROR_BITS_P2 if protocol == 2 else STATUS_ERROR_BITS_P1
    if protocol == 1:
        bits &= HW_ERROR_MASK_P1
    return [name for bit, name in names.items() if bits & (1 << bit)]
