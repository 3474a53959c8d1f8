"""Stop means stop: a ``stop`` ends the running gripper motion and every queued one (each answered
``stopped``), the queue is bounded, and callers that gave up leave no motion behind. The service
runs as its own process (``sofia gripper serve --emulate``), driven over a real Zenoh session."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable

import pytest
import zenoh
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import ErrorReply, GripperResult, GripperState, ServiceStatus

from ..conftest import Proc, first_reply, reply_ok

QUEUE_DEPTH = 4  # sofia_gripper.command_queue.QUEUE_DEPTH


@pytest.fixture
def gripper_service(sofia_proc: Callable[..., Proc]) -> Proc:
    proc = sofia_proc("gripper", "serve", "--emulate", "--baud", "1000000")
    proc.wait_for_log("gripper service ready", timeout=30)
    return proc


class Openings:
    """The opening of every published gripper state, with its receive time."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.samples: list[tuple[float, float]] = []

    def __call__(self, sample: zenoh.Sample) -> None:
        state = GripperState.model_validate_json(sample.payload.to_bytes())
        if state.opening_mm is not None:
            with self.lock:
                self.samples.append((time.monotonic(), state.opening_mm))

    def span_since(self, t0: float) -> tuple[int, float]:
        """(number of states, max - min opening in mm) received after ``t0``."""
        with self.lock:
            openings = [mm for t, mm in self.samples if t >= t0]
        return len(openings), (max(openings) - min(openings)) if openings else 0.0


def send(session: zenoh.Session, key: str, action: str, timeout: float,
         replies: list[zenoh.Reply] | None = None) -> None:  # fmt: skip
    """A command whose caller waits ``timeout`` seconds (keeping the replies in ``replies``)."""
    handler = replies.append if replies is not None else (lambda _reply: None)
    session.get(key, handler=handler, payload=json.dumps({"action": action, "speed": 0.05, "timeout_s": 20}),
                encoding=ENCODING_JSON, timeout=timeout)  # fmt: skip
    time.sleep(0.05)  # in order, and the running one taken off the queue first


def stop_and_watch(session: zenoh.Session, keys: Keys, openings: Openings) -> float:
    """Send ``stop``, then return how far the fingers moved (mm) in the 1.5 s after 0.3 s of settling."""
    stopped = reply_ok(first_reply(session, keys.gripper_command, '{"action": "stop"}'), GripperResult)
    assert stopped.ok, stopped.reason
    time.sleep(0.3)
    t0 = time.monotonic()
    time.sleep(1.5)
    n, span_mm = openings.span_since(t0)
    assert n >= 50, f"only {n} gripper states in 1.5 s"
    return span_mm


def test_stop_cancels_running_and_queued_commands(gripper_service: Proc, session: zenoh.Session,
                                                  robot_id: str) -> None:  # fmt: skip
    keys = Keys(robot_id)
    openings = Openings()
    sub = session.declare_subscriber(keys.gripper_state, openings)
    assert reply_ok(
        first_reply(session, keys.gripper_command, '{"action": "open"}', timeout=30), GripperResult
    ).ok

    replies: list[zenoh.Reply] = []
    for i in range(QUEUE_DEPTH + 2):  # one running, QUEUE_DEPTH waiting, one refused
        send(session, keys.gripper_command, "close" if i % 2 == 0 else "open", 20.0, replies)
    time.sleep(0.3)
    assert stop_and_watch(session, keys, openings) < 1.0
    deadline = time.monotonic() + 5
    while len(replies) < QUEUE_DEPTH + 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert len(replies) == QUEUE_DEPTH + 2, f"{len(replies)} replies"
    errors = [ErrorReply.model_validate_json(r.err.payload.to_bytes()) for r in replies if r.err is not None]
    results = [
        GripperResult.model_validate_json(r.ok.payload.to_bytes()) for r in replies if r.ok is not None
    ]
    assert [e.error for e in errors] == ["QueueFull"] and "queued" in errors[0].message
    assert len(results) == QUEUE_DEPTH + 1 and not any(r.ok for r in results)
    assert all(r.reason.startswith("stopped") for r in results), [r.reason for r in results]
    assert sum("before it started" in r.reason for r in results) == QUEUE_DEPTH

    # callers that gave up after 0.3 s: their commands are gone after the stop, nothing moves
    for i in range(12):
        send(session, keys.gripper_command, "close" if i % 2 == 0 else "open", 0.3)
    time.sleep(0.5)
    assert stop_and_watch(session, keys, openings) < 1.0
    status = ServiceStatus.model_validate_json(
        first_reply(session, keys.status("gripper")).ok.payload.to_bytes()
    )  # type: ignore[union-attr]
    assert status.counters["stopped"] == 2 * QUEUE_DEPTH
    assert status.counters["queue_full"] == 1 + 12 - 1 - QUEUE_DEPTH
    sub.undeclare()
    assert gripper_service.stop() == 0


def test_queued_command_past_its_timeout_expires(gripper_service: Proc, session: zenoh.Session,
                                                 robot_id: str) -> None:  # fmt: skip
    keys = Keys(robot_id)
    assert reply_ok(
        first_reply(session, keys.gripper_command, '{"action": "open"}', timeout=30), GripperResult
    ).ok
    replies: list[zenoh.Reply] = []
    session.get(keys.gripper_command, handler=replies.append, payload='{"action": "close", "speed": 0.3, "timeout_s": 10}',
                encoding=ENCODING_JSON, timeout=20)  # fmt: skip
    time.sleep(0.05)
    late = reply_ok(
        first_reply(session, keys.gripper_command, '{"action": "open", "timeout_s": 0.2}'), GripperResult
    )
    assert not late.ok and late.reason.startswith("expired"), late.reason
    assert late.duration_s >= 0.2
    assert gripper_service.stop() == 0
