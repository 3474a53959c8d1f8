"""Every command through the driver, the real dynamixel_sdk and the emulated MX-64 on a pty."""

from __future__ import annotations

import threading
import time

import pytest
from sofia_gripper import Emulator, Gripper
from sofia_schemas.messages import GripperCommand as Cmd

from .conftest import connected, make_config


def test_start_up_configures_the_servo(gripper: Gripper, emulator: Emulator) -> None:
    s = emulator.servo
    assert s.get("operating_mode") == 5  # current-based position
    assert s.get("torque_enable") == 1
    assert s.get("bus_watchdog") == 10  # 200 ms / 20 ms
    assert s.get("return_delay_time") == 0
    assert abs(s.get("goal_current") * 3.36 - 600) < 3.4
    state = gripper.state
    assert state.connected and state.status == "ok" and state.torque_enabled
    assert state.opening_mm == pytest.approx(100.0, abs=0.5)
    assert state.voltage_v == pytest.approx(12.0) and state.temperature_c == pytest.approx(35.0, abs=1)


def test_close_open_move_release(gripper: Gripper, emulator: Emulator) -> None:
    r = gripper.execute(Cmd(action="close"))
    assert r.ok and r.reason == "done" and r.opening_mm == pytest.approx(0.0, abs=1.0)
    assert (
        abs(emulator.snapshot()["position"] - gripper.config.closed_ticks)
        <= gripper.config.position_tolerance_ticks
    )
    r = gripper.execute(Cmd(action="open"))
    assert r.ok and r.opening_mm == pytest.approx(100.0, abs=1.0)
    r = gripper.execute(Cmd(action="move", opening_mm=55.0))
    assert r.ok and r.reason == "done" and r.opening_mm == pytest.approx(55.0, abs=1.0)
    r = gripper.execute(Cmd(action="move", position_ticks=2000))
    assert r.ok and abs((r.state.position_ticks if r.state else 0) - 2000) <= 15
    r = gripper.execute(Cmd(action="release"))
    assert r.ok and r.opening_mm == pytest.approx(100.0, abs=1.0) and r.state and not r.state.grasped


@pytest.mark.parametrize("width_mm", [15.0, 42.0, 80.0])
def test_grasp_objects_of_several_widths(gripper: Gripper, emulator: Emulator, width_mm: float) -> None:
    emulator.set_object(width_mm)
    r = gripper.execute(Cmd(action="grasp", force_n=12.5))  # 500 mA at 25 N/A
    assert r.ok and r.grasped and r.reason == "stalled"
    assert r.opening_mm == pytest.approx(width_mm, abs=2.0)  # the soft fingers give a little
    assert r.state and r.state.grasped and r.state.current_ma == pytest.approx(500, abs=10)
    assert r.state.force_n == pytest.approx(12.5, abs=0.3)
    assert emulator.snapshot()["current_ma"] <= 500 + 3.4  # never above the commanded current
    assert gripper.next_state(1.0).grasped  # type: ignore[union-attr]
    r = gripper.execute(Cmd(action="release"))
    assert r.ok and not gripper.next_state(1.0).grasped  # type: ignore[union-attr]


def test_grasp_of_nothing_closes_fully_and_reports_not_grasped(gripper: Gripper) -> None:
    r = gripper.execute(Cmd(action="grasp", current_ma=300, speed=0.5))
    assert r.ok and r.grasped is False and r.reason == "done"
    assert r.opening_mm == pytest.approx(0.0, abs=1.0)


def test_stop_interrupts_a_slow_grasp(gripper: Gripper, emulator: Emulator) -> None:
    results = []
    t = threading.Thread(target=lambda: results.append(gripper.execute(Cmd(action="grasp", speed=0.05))))
    t.start()
    time.sleep(0.4)
    stop = gripper.execute(Cmd(action="stop"))
    t.join(5)
    assert stop.ok and results and not results[0].ok and "stop" in results[0].reason
    p0 = emulator.snapshot()["position"]
    time.sleep(0.2)
    assert abs(emulator.snapshot()["position"] - p0) < 3  # it stays where it was stopped


def test_torque_off_and_on_and_reboot(gripper: Gripper, emulator: Emulator) -> None:
    r = gripper.execute(Cmd(action="torque", enable=False))
    assert r.ok and emulator.servo.get("torque_enable") == 0
    assert not gripper.next_state(1.0).torque_enabled  # type: ignore[union-attr]
    r = gripper.execute(Cmd(action="torque", enable=True))
    assert r.ok and emulator.servo.get("torque_enable") == 1
    r = gripper.execute(Cmd(action="reboot"))
    assert r.ok and emulator.servo.get("torque_enable") == 1 and emulator.servo.get("operating_mode") == 5
    assert gripper.execute(Cmd(action="state")).state.connected  # type: ignore[union-attr]


def test_timeout_is_reported_and_motion_stopped(gripper: Gripper) -> None:
    r = gripper.execute(Cmd(action="close", speed=0.02, timeout_s=0.3))
    assert not r.ok and r.reason.startswith("timeout")


def test_state_loop_rate_and_freshness(gripper: Gripper) -> None:
    log = gripper.on_state
    n0 = len(log.states)  # type: ignore[union-attr]
    time.sleep(1.0)
    states = log.states[n0:]  # type: ignore[union-attr]
    assert len(states) >= 50
    stamps = [s.stamp_ns for s in states]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)


def test_protocol1_gripper(emulator_p1: Emulator) -> None:
    emulator_p1.set_object(30.0)
    with connected(make_config(emulator_p1.path, protocol=1)) as g:
        r = g.execute(Cmd(action="grasp", current_ma=400))
        assert r.ok and r.grasped and r.opening_mm == pytest.approx(30.0, abs=2.0)
        assert emulator_p1.servo.get("torque_limit") == round(400 / 4100 * 1023)
        r = g.execute(Cmd(action="open"))
        assert r.ok and r.opening_mm == pytest.approx(100.0, abs=1.0)
        emulator_p1.set_object(None)
        assert g.execute(Cmd(action="close")).reason == "done"


def test_open_blocked_by_something_fails_with_the_reason(gripper: Gripper, emulator: Emulator) -> None:
    assert gripper.execute(Cmd(action="move", opening_mm=20.0)).ok
    with emulator.lock:  # the fingers jam: the motor cannot turn any more
        emulator.servo.max_speed_ticks_s = lambda: 0.0  # type: ignore[method-assign]
    r = gripper.execute(Cmd(action="open"))
    assert not r.ok and r.reason.startswith("blocked at 20.") and r.grasped is False
