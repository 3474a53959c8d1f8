"""The gripper service as a separate process (--emulate), driven over Zenoh from this process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from collections.abc import Callable

import pytest
import zenoh
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import GripperResult, GripperState, ServiceStatus

from ..conftest import SOFIA, Collector, Proc, first_reply, reply_err, reply_ok


def query(session: zenoh.Session, key: str, payload: bytes) -> zenoh.Reply:
    return first_reply(session, key, payload, encoding=ENCODING_JSON)


def ok(reply: zenoh.Reply) -> GripperResult:
    return reply_ok(reply, GripperResult)


@pytest.fixture
def service(sofia_proc: Callable[..., Proc]) -> Proc:
    proc = sofia_proc("gripper", "serve", "--emulate", "--baud", "1000000", "--object-width", "40")
    proc.wait_for_log("gripper service ready", timeout=30)
    return proc


def test_service_over_zenoh(
    service: Proc, session: zenoh.Session, collect: Callable[[str], Collector], robot_id: str
) -> None:
    keys = Keys(robot_id)
    got = collect(keys.gripper_state)
    r = ok(query(session, keys.gripper_command, b'{"action": "grasp", "force_n": 10}'))
    assert r.ok and r.grasped and r.opening_mm == pytest.approx(40.0, abs=2.0)
    time.sleep(0.3)
    n0 = len(got.on(keys.gripper_state))
    time.sleep(2.0)
    recent = got.models(keys.gripper_state, GripperState)[n0:]
    assert len(recent) >= 100, f"{len(recent)} states in 2 s"  # >= 50 Hz
    assert all(s.connected and s.grasped for s in recent)

    e = reply_err(query(session, keys.gripper_command, b'{"action": "move", "opening_mm": 300}'))
    assert e.error == "OutOfRange" and "300" in e.message
    e = reply_err(query(session, keys.gripper_command, b"not json"))
    assert e.error == "PayloadError" and "not json" in e.message
    e = reply_err(query(session, keys.gripper_command, b""))
    assert e.error == "PayloadError" and "no payload" in e.message
    assert ok(query(session, keys.gripper_command, b'{"action": "release"}')).ok

    status = ServiceStatus.model_validate_json(
        query(session, keys.status("gripper"), b"").ok.payload.to_bytes()
    )  # type: ignore[union-attr]
    assert status.service == "gripper" and status.state == "ok" and status.counters["command_errors"] == 3
    assert service.stop() == 0


def test_cli_commands_against_the_service(service: Proc, robot_id: str) -> None:
    env = dict(os.environ, SOFIA_ROBOT=robot_id)

    def sofia(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([SOFIA, "gripper", *args], env=env, capture_output=True, text=True, timeout=60)

    done = sofia("grasp", "--force", "10", "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["grasped"] is True  # one object on one line
    text = sofia("grasp", "--force", "10")  # for people: one sentence, not JSON
    assert text.returncode == 0 and text.stdout.startswith("grasp: stalled, opening"), text.stdout
    bad = sofia("move", "--opening", "500")
    assert bad.returncode == 1 and bad.stderr.startswith(
        "sofia gripper move: error: move opening 500 mm is outside"
    )
    assert bad.stderr.count("\n") == 1  # one line
    assert sofia("open").returncode == 0
    state = sofia("state", "--json")
    assert state.returncode == 0 and json.loads(state.stdout)["state"]["connected"] is True
    state_text = sofia("state")
    assert state_text.returncode == 0 and "connected: True" in state_text.stdout, state_text.stdout
    health = subprocess.run([SOFIA, "health", "gripper"], env=env, capture_output=True, text=True, timeout=60)
    assert health.returncode == 0 and health.stdout.startswith("gripper: ok"), health.stdout + health.stderr
    health_json = subprocess.run([SOFIA, "health", "gripper", "--json"], env=env, capture_output=True, text=True,
                                 timeout=60)  # fmt: skip
    assert json.loads(health_json.stdout)["state"] == "ok", health_json.stdout + health_json.stderr
    invalid = sofia("grasp", "--force", "-3")
    assert invalid.returncode == 2 and "force_n" in invalid.stderr


def test_service_without_hardware_keeps_serving_clear_errors(
    sofia_proc: Callable[..., Proc], session: zenoh.Session, robot_id: str
) -> None:
    proc = sofia_proc("gripper", "serve", "--port", "/nonexistent/ttyUSB9", "--baud", "57600")
    proc.wait_for_log("gripper service ready", timeout=30)
    keys = Keys(robot_id)
    e = reply_err(query(session, keys.gripper_command, b'{"action": "open"}'))
    assert e.error == "NotReady" and "/nonexistent/ttyUSB9" in e.message
    state = ok(query(session, keys.gripper_command, b'{"action": "state"}')).state
    assert state and not state.connected and state.status == "disconnected" and state.position_ticks is None
    status = ServiceStatus.model_validate_json(
        query(session, keys.status("gripper"), b"").ok.payload.to_bytes()
    )  # type: ignore[union-attr]
    assert status.state == "error" and "/nonexistent/ttyUSB9" in status.detail
    assert proc.stop() == 0


def test_service_moves_again_after_a_stall_trips_the_bus_watchdog(
    service: Proc, session: zenoh.Session, robot_id: str
) -> None:
    """A service stalled for longer than the servo's 200 ms Bus Watchdog (SIGSTOP for 1 s) trips it:
    the servo stops and refuses goals until the watchdog is cleared. The service clears and re-arms
    it and the next command moves the gripper (e-Manual, "Bus Watchdog(98)")."""
    keys = Keys(robot_id)
    assert ok(query(session, keys.gripper_command, b'{"action": "open"}')).ok
    os.kill(service.popen.pid, signal.SIGSTOP)  # the service only: its emulated servo runs on
    time.sleep(1.0)
    os.kill(service.popen.pid, signal.SIGCONT)
    r = ok(query(session, keys.gripper_command, b'{"action": "move", "opening_mm": 60}'))
    assert r.ok and r.opening_mm == pytest.approx(60.0, abs=1.5), r.reason
    assert r.state is not None and r.state.watchdog_trips >= 1
    assert service.stop() == 0
