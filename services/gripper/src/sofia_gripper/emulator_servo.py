"""The emulated MX-64: its control table (bytes, as on the servo) and a motor model.

Behaviour follows the ROBOTIS e-Manual (MX-64(2.0), MX-64AR/AT Protocol 1.0); what a Write
accepts is in :mod:`.emulator_rules`. The profile generator moves a trajectory point from the
present position to Goal Position at Profile Velocity; Moving(122) / Moving(46) is 1 while that
profile is in progress, whatever the motor does ("Moving(122)": "always set to 1 regardless of
Present Velocity while Profile is in progress"), and afterwards 1 only while the speed is above
Moving Threshold(24). The motor follows the trajectory point with a current that grows with
speed, capped by Goal Current (Protocol 2.0, current-based position mode) or Torque Limit(34)
(Protocol 1.0). An object between the fingers blocks the motor at ``object_ticks`` (closing
increases the position): the position stalls a little past contact (the soft fingers give) and
the current rises to its cap while the profile runs on to its end. Temperature follows I^2
heating and Newtonian cooling. Shutdown: a hardware error in the Shutdown mask clears Torque
Enable (Protocol 2.0, cleared by Reboot) or sets Torque Limit(34) to 0 (Protocol 1.0 "Alarm
Shutdown", recovered by writing it non-zero). Bus Watchdog(98) runs only while the torque is on.
"""

from __future__ import annotations

import math
import time

from dynamixel_sdk.protocol1_packet_handler import ERRBIT_OVERHEAT as P1_OVERHEAT

from .control_table import (
    ALERT_BIT_P2,
    MODEL,
    OPERATING_MODE_CURRENT_BASED_POSITION,
    STALL_CURRENT_MA,
    TICKS_PER_REV,
    UNITS,
    WATCHDOG_TRIPPED,
    WATCHDOG_UNIT_MS,
    Field,
    Protocol,
    decode_int,
    encode_int,
    fields,
)
from .emulator_rules import check_write, partial_item

AMBIENT_C = 35.0
HEAT_PER_MA2 = 1.25e-7  # degC / s per mA^2
COOL_PER_S = 1.0 / 60.0
COMPLIANCE_TICKS_PER_MA = 0.02  # how far the soft fingers give per mA of squeezing current
MAX_STEP_S = 0.002
LAG_CURRENT_MA_PER_TICK = 10.0  # position-loop current per tick of lag behind the trajectory
HW_OVERHEAT, HW_OVERLOAD = 1 << 2, 1 << 5  # Protocol 2.0 Hardware Error Status bits

DEFAULTS: dict[Protocol, dict[str, int]] = {
    2: {
        "firmware_version": 41, "baud_rate": 1, "return_delay_time": 250, "operating_mode": 3,
        "moving_threshold": 10, "temperature_limit": 80, "max_voltage_limit": 160,
        "min_voltage_limit": 95, "pwm_limit": 885, "current_limit": 1941, "acceleration_limit": 32767,
        "velocity_limit": 435, "max_position_limit": 4095, "min_position_limit": 0, "shutdown": 52,
        "status_return_level": 2, "goal_current": 1941,
    },
    1: {
        "firmware_version": 41, "baud_rate": 34, "return_delay_time": 250, "temperature_limit": 80,
        "max_voltage_limit": 240, "min_voltage_limit": 60, "max_torque": 1023,
        "max_position_limit": 4095, "min_position_limit": 0, "status_return_level": 2, "shutdown": 36,
        "alarm_led": 36, "torque_limit": 1023, "present_current": 2048,
    },
}  # fmt: skip


class Mx64Servo:
    """Control table and motor state of one emulated MX-64 (not thread-safe: the caller locks)."""

    def __init__(self, protocol: Protocol, dxl_id: int = 1, position_ticks: float = 2048.0) -> None:
        self.protocol, self.units, self.table = protocol, UNITS[protocol], fields(protocol)
        self.mem = bytearray(700 if protocol == 2 else 80)
        self.position, self.velocity, self.current_ma = float(position_ticks), 0.0, 0.0
        self.trajectory = self.position  # the profile generator's position (ticks)
        self.temperature_c, self.voltage_v = AMBIENT_C, 12.0
        self.hw_error = 0  # P2 Hardware Error Status bits / P1 hardware bits of the error byte
        self.object_ticks: float | None = None
        self.t_last = time.monotonic()
        self.t_last_packet = self.t_last
        self.t_boot = self.t_last
        self.registered: tuple[int, bytes] | None = None
        self.factory_reset(dxl_id)

    # --- control table ----------------------------------------------------
    def get(self, name: str) -> int:
        f = self.table[name]
        return decode_int(self.mem, f.address, f)

    def set(self, name: str, value: int) -> None:
        f = self.table[name]
        self.mem[f.address : f.address + f.size] = encode_int(int(value), f)

    def factory_reset(self, dxl_id: int) -> None:
        self.mem[:] = bytes(len(self.mem))
        self.set("model_number", MODEL[self.protocol])
        self.set("id", dxl_id)
        for name, value in DEFAULTS[self.protocol].items():
            self.set(name, value)
        self.reboot()

    def reboot(self) -> None:
        """Power-on RAM ("Reboot": RAM area back to its initial values, EEPROM kept); hardware
        errors cleared if their cause is gone."""
        defaults = DEFAULTS[self.protocol]
        for name, f in self.table.items():
            if not f.eeprom and f.writable:
                self.set(name, defaults.get(name, 0))
        self.set("goal_position", round(self.position))
        if self.protocol == 2:
            self.set("status_return_level", defaults["status_return_level"])
            self.set("goal_current", self.get("current_limit"))
            self.set("goal_pwm", self.get("pwm_limit"))
        else:
            self.set("torque_limit", self.get("max_torque"))  # copied from Max Torque at power-on
        self.trajectory = self.position
        self.hw_error &= HW_OVERHEAT if self.temperature_c >= self.get("temperature_limit") else 0
        self.registered = None
        self.t_boot = time.monotonic()

    def _fields_in(self, address: int, length: int) -> list[tuple[str, Field]]:
        return [
            (n, f)
            for n, f in self.table.items()
            if f.address < address + length and address < f.address + f.size
        ]

    def write(self, address: int, data: bytes) -> int:
        """Apply a Write; returns the status error (P2 error number or P1 error bits), 0 if fine."""
        p2 = self.protocol == 2
        touched = self._fields_in(address, len(data))
        new = bytearray(self.mem)
        new[address : address + len(data)] = data
        error = check_write(self.protocol, touched, new, self.get, partial_item(touched, address, len(data)))
        if error:
            return error
        names = {n for n, _ in touched}
        mode = self.get("operating_mode") if p2 else 0
        profiling = abs(self.get("goal_position") - self.trajectory) > 0.5
        self.mem[address : address + len(data)] = data
        if "goal_position" in names and not profiling:
            self.trajectory = self.position  # a new profile starts from the present position
        if p2 and "operating_mode" in names and self.get("operating_mode") != mode:
            # "Operating Mode(11)" note: profile reset to 0, Goal PWM/Current to their limits
            self.set("profile_velocity", 0)
            self.set("profile_acceleration", 0)
            self.set("goal_pwm", self.get("pwm_limit"))
            self.set("goal_current", self.get("current_limit"))
        if not p2 and "torque_limit" in names and self.get("torque_limit") > 0:
            # "Alarm Shutdown": writing Torque Limit(34) non-zero makes the motor usable again
            self.hw_error &= P1_OVERHEAT if self.temperature_c >= self.get("temperature_limit") else 0
        if "bus_watchdog" in names:
            self.t_last_packet = time.monotonic()
        return 0

    def read(self, address: int, length: int) -> bytes:
        self.refresh_registers()
        return bytes(self.mem[address : address + length])

    # --- motor model ------------------------------------------------------
    def current_cap_ma(self) -> float:
        if self.protocol == 2:
            if self.get("operating_mode") == OPERATING_MODE_CURRENT_BASED_POSITION:
                return abs(self.get("goal_current")) * self.units.current_ma
            return self.get("current_limit") * self.units.current_ma
        return min(self.get("torque_limit"), self.get("max_torque")) / 1023 * STALL_CURRENT_MA

    def speed_ticks_s(self) -> float:
        units = self.get("profile_velocity")
        if units == 0:
            units = self.get("velocity_limit") if self.protocol == 2 else 1023
        return units * self.units.velocity_rpm / 60.0 * TICKS_PER_REV

    def advance(self, now: float) -> None:
        """Integrate the motor from the last call to ``now`` (s, monotonic)."""
        while self.t_last < now:
            dt = min(MAX_STEP_S, now - self.t_last)
            self._step(dt, self.t_last + dt)
            self.t_last += dt

    def max_speed_ticks_s(self) -> float:
        """How fast the motor can follow its trajectory (Velocity Limit; P1: 1023 units)."""
        units = self.get("velocity_limit") if self.protocol == 2 else 1023
        return units * self.units.velocity_rpm / 60.0 * TICKS_PER_REV

    def profiling(self) -> bool:
        """Whether a Goal Position profile is in progress."""
        return abs(self.get("goal_position") - self.trajectory) > 0.5

    def _step(self, dt: float, now: float) -> None:
        p2 = self.protocol == 2
        on = bool(self.get("torque_enable"))
        wd = self.get("bus_watchdog") if p2 else 0
        if on and 0 < wd < WATCHDOG_TRIPPED and now - self.t_last_packet > wd * WATCHDOG_UNIT_MS / 1000:
            self.set("bus_watchdog", WATCHDOG_TRIPPED)  # "Bus Watchdog(98)": the servo stops
            self.set("goal_position", round(self.position))
            self.trajectory = self.position
        cap = self.current_cap_ma()
        if on and cap > 0:
            err_t = self.get("goal_position") - self.trajectory
            self.trajectory += math.copysign(min(abs(err_t), self.speed_ticks_s() * dt), err_t)
            err = self.trajectory - self.position
            step = math.copysign(min(abs(err), self.max_speed_ticks_s() * dt), err)
            target = self.position + step
            # current-based position control: current grows with speed and with the lag behind
            # the trajectory (a jammed motor pushes with its full current)
            current = 40.0 + 0.15 * abs(step / dt) + LAG_CURRENT_MA_PER_TICK * abs(self.trajectory - target)
            contact = None if self.object_ticks is None else self.object_ticks + COMPLIANCE_TICKS_PER_MA * cap
            if contact is not None and step > 0 and target >= contact:
                target, current = max(self.position, contact), cap
            self.velocity = (target - self.position) / dt
            self.position, self.current_ma = target, min(current, cap)
        else:
            self.velocity, self.current_ma = 0.0, 0.0
            if not on:
                self.trajectory = self.position
        heat = HEAT_PER_MA2 * self.current_ma**2 - COOL_PER_S * (self.temperature_c - AMBIENT_C)
        self.temperature_c += heat * dt
        if self.temperature_c >= self.get("temperature_limit"):
            self.hw_error |= HW_OVERHEAT if p2 else P1_OVERHEAT
        if self.hw_error & self.get("shutdown"):
            if p2 and on:
                self.set("torque_enable", 0)
            elif not p2 and self.get("torque_limit"):
                self.set("torque_limit", 0)  # "Alarm Shutdown": output 0 % through Torque Limit(34)

    def refresh_registers(self) -> None:
        """Write the motor state into the present-value registers."""
        u = self.units
        self.set("present_position", round(self.position) % (1 << u.position_bits))
        vel = round(self.velocity * 60.0 / TICKS_PER_REV / u.velocity_rpm)
        cur = round(self.current_ma / u.current_ma)
        self.set("present_temperature", round(self.temperature_c))
        threshold = self.get("moving_threshold") if self.protocol == 2 else 1
        self.set("moving", int(self.profiling() or abs(vel) > threshold))
        self.set("realtime_tick", int((time.monotonic() - self.t_boot) * 1000) % 32768)
        if self.protocol == 2:
            self.set("present_velocity", vel)
            self.set("present_current", cur)
            self.set("present_input_voltage", round(self.voltage_v * 10))
            self.set("hardware_error_status", self.hw_error)
            in_position = abs(self.get("goal_position") - self.position) < 20
            self.set("moving_status", int(in_position) | (int(self.profiling()) << 1))
            traj_vel = round(self.speed_ticks_s() * 60.0 / TICKS_PER_REV / u.velocity_rpm)
            self.set("velocity_trajectory", traj_vel if self.profiling() else 0)
            self.set("position_trajectory", round(self.trajectory))
        else:
            self.set("present_velocity", min(abs(vel), 1023) | (1024 if vel < 0 else 0))
            self.set("present_current", u.current_offset + cur)
            load = min(1023, round(self.current_ma / STALL_CURRENT_MA * 1023))
            self.set("present_load", load | (1024 if vel < 0 else 0))
            self.set("present_input_voltage", round(self.voltage_v * 10))

    def status_error(self) -> int:
        """Error byte carried by every status packet: P2 alert bit, P1 hardware bits."""
        if self.protocol == 2:
            return ALERT_BIT_P2 if self.hw_error else 0
        return self.hw_error
