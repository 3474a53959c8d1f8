"""The emulator and the driver against the ROBOTIS e-Manual, section by section.

Each test names the e-Manual section (MX-64(2.0) or MX-64AR/AT Protocol 1.0 control table, or
the Protocol 2.0 specification) whose behaviour it checks, through the real dynamixel_sdk over
the emulator's pty.
"""

from __future__ import annotations

import threading
import time

import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, GroupSyncRead, PacketHandler, PortHandler
from sofia_gripper import Emulator, Gripper, GripperError, NotReady
from sofia_gripper.control_table import WATCHDOG_TRIPPED
from sofia_schemas.messages import GripperCommand as Cmd

from .conftest import connected, make_config, wait_until

P2_ERR_DATA_RANGE, P2_ERR_DATA_LENGTH, P2_ERR_LIMIT = 4, 5, 6


# --- Bus Watchdog(98) ------------------------------------------------------------------------


def test_bus_watchdog_trip_is_cleared_and_the_command_goes_through(
    gripper: Gripper, emulator: Emulator
) -> None:
    """ "Bus Watchdog(98)": after a trip the goal values are read-only (Data Range Error) until 0 is
    written. A host stall (the line held for 0.5 s) trips it; the next command still succeeds."""
    with gripper.bus.lock:  # the host stalls: no packet for longer than the 200 ms watchdog
        time.sleep(0.5)
        assert emulator.snapshot()["watchdog"] == WATCHDOG_TRIPPED
    r = gripper.execute(Cmd(action="move", opening_mm=60))
    assert r.ok, r.reason
    assert gripper.counters["watchdog_trips"] == 1 and emulator.servo.get("bus_watchdog") == 10
    wait_until(lambda: gripper.state.watchdog_trips == 1, 2.0, "trip reported in the state")


def test_stop_after_a_bus_watchdog_trip_clears_it_and_holds(gripper: Gripper, emulator: Emulator) -> None:
    """ "Bus Watchdog(98)": a stop that comes after a trip (a host stall) still holds the fingers
    where they are: its Goal Position write clears the trip instead of failing on Data Range."""
    with gripper.bus.lock:
        time.sleep(0.5)
        assert emulator.snapshot()["watchdog"] == WATCHDOG_TRIPPED
    r = gripper.execute(Cmd(action="stop"))
    assert r.ok, r.reason
    assert gripper.counters["watchdog_trips"] == 1 and emulator.servo.get("bus_watchdog") == 10


def test_bus_watchdog_trip_during_a_grasp_resends_the_goal(gripper: Gripper, emulator: Emulator) -> None:
    emulator.set_object(40.0)
    results = []
    worker = threading.Thread(target=lambda: results.append(gripper.execute(Cmd(action="grasp", speed=0.1))))
    worker.start()
    time.sleep(0.3)  # the fingers are on their way
    with gripper.bus.lock:
        time.sleep(0.5)
    worker.join(20)
    assert results and results[0].ok and results[0].grasped, results
    assert results[0].opening_mm == pytest.approx(40.0, abs=2.0)
    assert gripper.counters["watchdog_trips"] >= 1


def test_bus_watchdog_trip_right_after_the_goal_resends_it(
    gripper: Gripper, emulator: Emulator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """ "Bus Watchdog(98)": a trip drops the goal just written. When the host stalls right after
    the goal and the state loop clears the trip before the command waits for the motion, the
    command still sends the goal again instead of reporting the fingers blocked where they stand."""
    set_goal = gripper.servo.set_goal

    def set_goal_then_stall(ticks: float) -> int:
        goal = set_goal(ticks)
        monkeypatch.undo()  # once
        with gripper.bus.lock:  # the host stalls before the servo moved
            emulator.servo.advance(time.monotonic())
            time.sleep(0.5)
        assert gripper.servo.recover_watchdog()  # the state loop sees the trip first
        return goal

    monkeypatch.setattr(gripper.servo, "set_goal", set_goal_then_stall)
    emulator.set_object(40.0)
    r = gripper.execute(Cmd(action="grasp"))
    assert r.ok and r.grasped, r.reason
    assert r.opening_mm == pytest.approx(40.0, abs=2.0)
    assert gripper.counters["watchdog_trips"] == 1


def test_bus_watchdog_runs_only_with_torque_on(emulator: Emulator, port: PortHandler) -> None:
    """ "Bus Watchdog(98)": it monitors the communication interval when Torque Enable is 1."""
    ph = PacketHandler(2.0)
    assert ph.write1ByteTxRx(port, 1, 98, 5) == (COMM_SUCCESS, 0)  # 100 ms, torque off
    time.sleep(0.3)
    assert ph.read1ByteTxRx(port, 1, 98)[0] == 5
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (COMM_SUCCESS, 0)
    time.sleep(0.3)
    assert ph.read1ByteTxRx(port, 1, 98)[0] == WATCHDOG_TRIPPED
    assert ph.write4ByteTxRx(port, 1, 116, 2000) == (COMM_SUCCESS, P2_ERR_DATA_RANGE)
    assert ph.write1ByteTxRx(port, 1, 98, 0) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, 116, 2000) == (COMM_SUCCESS, 0)


# --- Moving(122) and stall detection ------------------------------------------------------------


def test_moving_stays_set_while_the_profile_runs_and_the_grasp_reports_on_the_stall(
    gripper: Gripper, emulator: Emulator
) -> None:
    """ "Moving(122)": 1 while the profile is in progress, even if the fingers stopped on an object.
    The driver reports the grasp from the stall (speed ~ 0, current at the goal), long before the
    profile ends."""
    emulator.set_object(60.0)
    speed = 0.2
    t0 = time.monotonic()
    r = gripper.execute(Cmd(action="grasp", speed=speed))
    took = time.monotonic() - t0
    assert r.ok and r.reason == "stalled" and r.grasped and r.opening_mm == pytest.approx(60.0, abs=2.0)
    with emulator.lock:
        emulator.servo.advance(time.monotonic())
        emulator.servo.refresh_registers()
        still_profiling = emulator.servo.get("moving") == 1 and emulator.servo.profiling()
    assert still_profiling, "Moving must stay 1 until the profile ends"
    c = gripper.config
    travel_ticks = c.closed_ticks - c.open_ticks
    profile_s = travel_ticks / (c.max_velocity_rpm * speed / 60 * 4096)
    assert took < 0.8 * profile_s, f"grasp took {took:.2f} s, profile {profile_s:.2f} s"


# --- Protocol 1.0 Alarm Shutdown / Torque Limit(34) ----------------------------------------------


def test_protocol1_shutdown_sets_torque_limit_to_zero_and_torque_on_recovers(
    emulator_p1: Emulator, overloaded_p1: Gripper
) -> None:
    """MX-64AR/AT "Alarm Shutdown": the output becomes 0 % by setting Torque Limit(34) to 0; the
    servo is usable again once it is written non-zero."""
    g = overloaded_p1
    assert emulator_p1.servo.get("torque_limit") == 0 and emulator_p1.servo.get("torque_enable") == 1
    assert "torque on" in (g.state.error or "") and "reboot" not in (g.state.error or "")
    with pytest.raises(NotReady, match="overload"):
        g.execute(Cmd(action="close"))
    assert g.execute(Cmd(action="torque", enable=True)).ok
    assert emulator_p1.servo.get("torque_limit") > 0
    wait_until(lambda: g.state.status == "ok", 2.0, "ok after torque on")
    assert g.execute(Cmd(action="close")).ok


# --- Min/Max Position Limit(48, 52) ----------------------------------------------------------------


def test_current_based_position_mode_ignores_position_limits(emulator: Emulator, port: PortHandler) -> None:
    """ "Min/Max Position Limit": used in Position Control Mode only, not in Current-based Position
    Control Mode (goals within +-1,048,575)."""
    ph = PacketHandler(2.0)
    assert ph.write4ByteTxRx(port, 1, 48, 3000) == (COMM_SUCCESS, 0)  # Max Position Limit
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (COMM_SUCCESS, 0)  # position mode (3)
    assert ph.write4ByteTxRx(port, 1, 116, 3500) == (COMM_SUCCESS, P2_ERR_LIMIT)
    assert ph.write1ByteTxRx(port, 1, 64, 0) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, 11, 5) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, 116, 3500) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, 116, 2_000_000) == (COMM_SUCCESS, P2_ERR_LIMIT)


def test_driver_clamps_to_the_calibrated_range_whatever_the_servo_limits(emulator: Emulator) -> None:
    emulator.servo.set("max_position_limit", 1500)  # would exclude the calibrated range in mode 3
    with connected(make_config(emulator.path)) as g:
        assert g.servo.limits == (g.config.open_ticks, g.config.closed_ticks)
        assert (
            g.servo.set_goal(10_000) == g.config.closed_ticks and g.servo.set_goal(-5) == g.config.open_ticks
        )


def test_protocol1_angle_limits_excluding_the_range_are_named(emulator_p1: Emulator) -> None:
    emulator_p1.servo.set("max_position_limit", 1400)
    g = Gripper(make_config(emulator_p1.path, protocol=1))
    with pytest.raises(GripperError, match=r"Angle Limit \[0, 1400\].*1433\.\.2519"):
        g.bus.open()
        g.configure()
    g.bus.close()


# --- Protocol 2.0 specification and control table details -------------------------------------------


def test_broadcast_ping_is_answered(emulator: Emulator, port: PortHandler) -> None:
    """Protocol 2.0 "Ping": a broadcast ping (ID 0xFE) is answered by every device."""
    found, result = PacketHandler(2.0).broadcastPing(port)
    assert result == COMM_SUCCESS and found.get(1, [None])[0] == 311


def test_short_write_gets_data_length_error(emulator: Emulator, port: PortHandler) -> None:
    """Protocol 2.0 status error 0x05 Data Length Error: fewer bytes than the item holds."""
    ph = PacketHandler(2.0)
    assert ph.write2ByteTxRx(port, 1, 116, 2000) == (COMM_SUCCESS, P2_ERR_DATA_LENGTH)


def test_reboot_restores_ram_and_operating_mode_change_resets_goals(
    emulator: Emulator, port: PortHandler
) -> None:
    """ "Reboot" restores the RAM area; "Operating Mode(11)": switching resets Profile Velocity and
    Acceleration to 0 and Goal Current to Current Limit(38)."""
    ph = PacketHandler(2.0)
    assert ph.write4ByteTxRx(port, 1, 112, 77) == (COMM_SUCCESS, 0)
    assert ph.write2ByteTxRx(port, 1, 102, 100) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, 11, 5) == (COMM_SUCCESS, 0)
    assert ph.read4ByteTxRx(port, 1, 112)[0] == 0 and ph.read2ByteTxRx(port, 1, 102)[0] == 1941
    assert ph.write4ByteTxRx(port, 1, 112, 77) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, 65, 1) == (COMM_SUCCESS, 0)  # LED
    assert ph.reboot(port, 1) == (COMM_SUCCESS, 0)
    assert ph.read4ByteTxRx(port, 1, 112)[0] == 0 and ph.read1ByteTxRx(port, 1, 65)[0] == 0
    assert ph.read1ByteTxRx(port, 1, 11)[0] == 5  # EEPROM kept


def test_status_return_level_applies_to_sync_read(emulator: Emulator, port: PortHandler) -> None:
    """ "Status Return Level(68)": 0 answers PING only; Sync Read is a READ instruction."""
    ph = PacketHandler(2.0)
    sr = GroupSyncRead(port, ph, 132, 4)
    sr.addParam(1)
    assert sr.txRxPacket() == COMM_SUCCESS
    assert ph.write1ByteTxRx(port, 1, 68, 0)[0] == COMM_RX_TIMEOUT  # level 0: no status to the write
    assert sr.txRxPacket() == COMM_RX_TIMEOUT
    assert ph.ping(port, 1)[1] == COMM_SUCCESS


def test_protocol1_max_voltage_limit_default() -> None:
    """MX-64AR/AT control table: Max Voltage Limit(13) initial value 240 (24 V)."""
    from sofia_gripper.emulator_servo import Mx64Servo

    assert Mx64Servo(1).get("max_voltage_limit") == 240 and Mx64Servo(2).get("max_voltage_limit") == 160


# --- driver behaviour -------------------------------------------------------------------------------


def test_reconnect_does_not_rewrite_eeprom(emulator: Emulator) -> None:
    """EEPROM has limited write cycles: a reconnect writes Return Delay Time / Operating Mode only
    when they differ."""
    writes: list[int] = []
    servo_write = emulator.servo.write

    def counting_write(address: int, data: bytes) -> int:
        if any(f.eeprom for _, f in emulator.servo._fields_in(address, len(data))):
            writes.append(address)
        return servo_write(address, data)

    emulator.servo.write = counting_write  # type: ignore[method-assign]
    for _ in range(2):
        g = Gripper(make_config(emulator.path))
        g.start()
        wait_until(lambda: g.state.connected, 3.0, "connected")  # noqa: B023
        g.close()  # torque off: the next start configures again
    assert sorted(writes) == [9, 11], writes  # once each, at the first start


def test_supply_voltage_error_says_check_the_supply(gripper: Gripper, emulator: Emulator) -> None:
    with emulator.lock:
        emulator.servo.hw_error |= 1  # Input Voltage Error
    wait_until(lambda: gripper.state.status == "error", 2.0, "error state")
    assert "check the supply" in (gripper.state.error or "")
