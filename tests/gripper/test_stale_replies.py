"""Status packets that are cut or late (Protocol 2.0 replies carry no request id) never become a
published state; torque on after a shutdown answers "reboot needed"."""

from __future__ import annotations

import time

import pytest
from sofia_gripper import Emulator, Gripper, NotReady
from sofia_gripper.bus import DxlBus
from sofia_gripper.errors import CommFailed
from sofia_schemas.messages import GripperCommand as Cmd
from sofia_schemas.messages import GripperState

from .conftest import BAUD, StateLog, wait_until


def _decoded_from_a_real_reply(state: GripperState) -> bool:
    """A connected state whose values the emulated servo can have (about 12 V, 40 C, open)."""
    return (
        (state.voltage_v or 0.0) > 5.0
        and (state.temperature_c or 0.0) > 10.0
        and (state.position_ticks or 0) > 0
    )


def _connected(log: StateLog, since: int) -> list[GripperState]:
    return [s for s in log.states[since:] if s.connected]


def test_cut_status_packets_are_refused_by_name(emulator: Emulator) -> None:
    bus = DxlBus(emulator.path, BAUD, 2, 1)
    bus.open()
    try:
        assert bus.read("present_input_voltage") > 50
        emulator.cut = True
        with pytest.raises(CommFailed, match=r"status packet with 2 data bytes, expected 4: a stale or cut"):
            bus.read("present_position")
        with pytest.raises(CommFailed, match="state read: status packet with"):
            bus.read_state()
        emulator.cut = False
        assert bus.read("present_input_voltage") > 50  # the line is usable again
    finally:
        bus.close()


def test_cut_replies_give_disconnected_never_zeros(gripper: Gripper, emulator: Emulator) -> None:
    log = gripper.on_state
    assert isinstance(log, StateLog)
    start = len(log.states)
    emulator.cut = True
    wait_until(lambda: not gripper.state.connected, 3.0, "disconnected on cut replies")
    time.sleep(0.3)
    emulator.cut = False
    wait_until(lambda: gripper.state.connected and gripper.state.status == "ok", 3.0, "reconnected")
    states = _connected(log, start)
    assert states and all(_decoded_from_a_real_reply(s) for s in states), [
        s for s in states if not _decoded_from_a_real_reply(s)
    ][:1]
    assert gripper.counters["read_errors"] >= 1


def test_a_late_reply_is_never_taken_for_the_next_request(emulator: Emulator) -> None:
    """The host gives up on a request (its status timeout, ~34 ms here), sends the next one, and
    the first reply arrives before the second's: a state block where a 1-byte torque read waits, or
    a 1-byte reply where the state block waits (which once decoded as zeros). The late one is
    dropped by its size and the second read gets its own reply."""
    bus = DxlBus(emulator.path, BAUD, 2, 1)
    bus.open()
    try:
        bus.write("torque_enable", 1)
        state_size = len(bus.read_state()[0])
        for first, second in (("state", "torque_enable"), ("torque_enable", "state")):
            emulator.late_s = 0.05  # later than the first read's timeout, within the second's
            with pytest.raises(CommFailed, match="There is no status packet"):
                bus.read_state() if first == "state" else bus.read(first)
            stale = bus.stale_replies
            if second == "state":
                assert len(bus.read_state()[0]) == state_size
            else:
                assert bus.read(second) == 1
            assert bus.stale_replies == stale + 1  # the late reply was seen and dropped
    finally:
        bus.close()


def test_torque_on_after_a_shutdown_says_reboot_needed(gripper: Gripper, emulator: Emulator) -> None:
    assert gripper.execute(Cmd(action="close")).ok
    gripper.grasped = True  # as after a grasp that stalled on an object
    emulator.inject_overload()
    wait_until(lambda: gripper.state.status == "error" and not gripper.state.torque_enabled, 2.0, "shut down")
    wait_until(lambda: not gripper.state.grasped, 2.0, "grasped cleared with the torque off")
    with pytest.raises(NotReady, match="reboot needed: the servo shut down on overload"):
        gripper.execute(Cmd(action="torque", enable=True))
    assert emulator.servo.get("torque_enable") == 0
    emulator.clear_faults()
    assert gripper.execute(Cmd(action="reboot")).ok
    r = gripper.execute(Cmd(action="torque", enable=True))
    assert r.ok and emulator.servo.get("torque_enable") == 1


def test_torque_on_that_the_servo_undoes_is_not_ok(gripper: Gripper, emulator: Emulator) -> None:
    """The driver has not read the hardware error yet (the shutdown came between two state reads):
    the write is taken, the servo switches the torque off again, the answer is not ok."""
    emulator.servo.hw_error |= 0x20  # overload, seen by the servo before the driver's next read
    gripper.hw_error = []
    try:
        r = gripper.execute(Cmd(action="torque", enable=True))
        ok, reason = r.ok, r.reason
    except NotReady as e:  # the state loop read the error first: refused before writing
        ok, reason = False, str(e)
    assert not ok and "reboot needed" in reason
    assert emulator.servo.get("torque_enable") == 0
