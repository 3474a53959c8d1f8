"""Injected faults: a clear error state, no stale values, and recovery."""

from __future__ import annotations

import time

import pytest
from sofia_gripper import Emulator, Gripper, GripperError, NotReady
from sofia_gripper.bus import DxlBus
from sofia_gripper.control_table import MODEL
from sofia_gripper.errors import CommFailed
from sofia_gripper.service import EMULATED_REPLY_MARGIN_MS
from sofia_schemas.messages import GripperCommand as Cmd

from .conftest import BAUD, connected, make_config, wait_until


@pytest.mark.parametrize(
    ("inject", "word"), [("inject_overheat", "overheating"), ("inject_overload", "overload")]
)
def test_hardware_error_stops_reports_and_reboot_recovers(
    gripper: Gripper, emulator: Emulator, inject: str, word: str
) -> None:
    getattr(emulator, inject)()
    wait_until(lambda: gripper.state.status == "error", 2.0, "error state")
    state = gripper.state
    assert word in state.hardware_error and state.error and word in state.error and "reboot" in state.error
    assert emulator.servo.get("torque_enable") == 0  # the servo's shutdown switched the torque off
    with pytest.raises(NotReady, match=word):
        gripper.execute(Cmd(action="close"))
    if word == "overheating":  # still hot: the error survives a reboot
        r = gripper.execute(Cmd(action="reboot"))
        assert not r.ok and word in r.reason
        emulator.clear_faults()
    r = gripper.execute(Cmd(action="reboot"))
    assert r.ok, r.reason
    wait_until(lambda: gripper.state.status == "ok", 2.0, "ok after reboot")
    assert gripper.execute(Cmd(action="close")).ok


def test_driver_temperature_limit_stops_motion(gripper: Gripper, emulator: Emulator) -> None:
    emulator.servo.temperature_c = gripper.config.max_temperature_c + 3  # hot, below the servo's 80 C
    wait_until(lambda: gripper.state.status == "error", 2.0, "overheat state")
    assert "temperature" in (gripper.state.error or "")
    with pytest.raises(NotReady, match="temperature"):
        gripper.execute(Cmd(action="close"))
    emulator.clear_faults()
    wait_until(lambda: gripper.state.status == "ok", 2.0, "cooled down")
    assert gripper.execute(Cmd(action="close")).ok


@pytest.mark.parametrize("fault", ["no_reply", "corrupt"])
def test_dead_or_noisy_line_gives_disconnected_state_then_reconnects(
    gripper: Gripper, emulator: Emulator, fault: str
) -> None:
    setattr(emulator, fault, True)
    wait_until(lambda: not gripper.state.connected, 3.0, "disconnected")
    state = gripper.state
    assert state.status == "disconnected" and state.error
    assert (
        state.position_ticks is None and state.opening_mm is None and state.current_ma is None
    )  # nothing stale
    with pytest.raises(NotReady, match="serial line down"):
        gripper.execute(Cmd(action="open"))
    setattr(emulator, fault, False)
    wait_until(lambda: gripper.state.connected and gripper.state.status == "ok", 3.0, "reconnected")
    assert gripper.counters["reconnects"] >= 1
    assert gripper.execute(Cmd(action="close")).ok


def test_unplug_and_replug(gripper: Gripper, emulator: Emulator) -> None:
    emulator.unplug()
    wait_until(lambda: not gripper.state.connected, 3.0, "disconnected after unplug")
    assert "lost" in (gripper.state.error or "") or "open" in (gripper.state.error or "")
    time.sleep(0.5)  # reconnect attempts fail without crashing the loop
    assert gripper._thread is not None and gripper._thread.is_alive()
    emulator.replug()
    wait_until(lambda: gripper.state.connected, 3.0, "reconnected after replug")
    assert gripper.execute(Cmd(action="move", opening_mm=50)).ok


def test_bus_watchdog_stops_the_motor_when_the_driver_dies(emulator: Emulator) -> None:
    g = Gripper(make_config(emulator.path, watchdog_ms=100))
    g.start()
    wait_until(lambda: g.state.connected, 3.0, "connected")
    g.servo.set_speed(0.05)
    g.servo.set_goal(g.config.closed_ticks)
    time.sleep(0.2)
    g.close(torque_off=False)  # as if the service was killed: no more packets
    time.sleep(0.3)
    snap = emulator.snapshot()
    assert snap["watchdog"] == 0xFF and snap["torque"] == 1.0  # tripped; holding, not moving
    p0 = snap["position"]
    time.sleep(0.2)
    assert abs(emulator.snapshot()["position"] - p0) < 1 and p0 < g.config.closed_ticks - 100
    with connected(make_config(emulator.path)) as g2:  # a restarted service clears the watchdog and resumes
        assert emulator.servo.get("bus_watchdog") == 10 and g2.execute(Cmd(action="open")).ok


def test_start_up_without_a_servo_keeps_retrying(tmp_path) -> None:  # type: ignore[no-untyped-def]
    g = Gripper(make_config(str(tmp_path / "no-such-tty")))
    g.start()
    try:
        time.sleep(0.5)
        assert not g.state.connected and "no-such-tty" in (g.state.error or "")
        emu = Emulator(baud=1_000_000, link_path=tmp_path / "no-such-tty")
        emu.start()
        try:
            wait_until(lambda: g.state.connected, 3.0, "connected once the servo appears")
        finally:
            emu.stop()
    finally:
        g.close()


def test_wrong_model_is_refused(emulator: Emulator) -> None:
    emulator.servo.set("model_number", 1020)  # an XM430
    g = Gripper(make_config(emulator.path))
    g.start()
    try:
        time.sleep(0.3)
        assert not g.state.connected and "model 1020, expected MX-64 model 311" in (g.state.error or "")
    finally:
        g.close()


def test_protocol1_overload_is_reported_and_torque_on_rearms(overloaded_p1: Gripper) -> None:
    g = overloaded_p1
    assert g.state.hardware_error == ["overload"] and "send torque on" in (g.state.error or "")
    with pytest.raises(NotReady, match="overload"):
        g.execute(Cmd(action="open"))
    with pytest.raises(GripperError, match="no Reboot instruction"):
        g.execute(Cmd(action="reboot"))
    assert g.execute(Cmd(action="torque", enable=True)).ok
    wait_until(lambda: g.state.status == "ok", 2.0, "P1 re-armed")
    assert g.execute(Cmd(action="close")).ok


def test_a_late_servo_is_waited_for_with_the_reply_margin(
    emulator: Emulator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An emulated servo on a loaded host answers late: 80 ms here. dynamixel_sdk's own wait (about
    35 ms) gives up; with the margin `serve --emulate` sets, the same exchange succeeds."""
    handle = emulator._handle_bytes

    def late(data: bytes, t_arrival: float) -> None:
        time.sleep(0.08)
        handle(data, time.monotonic())

    monkeypatch.setattr(emulator, "_handle_bytes", late)
    patient = DxlBus(emulator.path, BAUD, 2, 1, timeout_margin_ms=EMULATED_REPLY_MARGIN_MS)
    patient.open()
    assert patient.ping() == MODEL[2]
    patient.close()
    hasty = DxlBus(emulator.path, BAUD, 2, 1)
    hasty.open()
    with pytest.raises(CommFailed, match="ping"):
        hasty.ping()
    hasty.close()
