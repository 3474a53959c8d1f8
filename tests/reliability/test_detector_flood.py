"""A burst of detect queries four times the detector's query queue, sent at once to the running
service: every query gets exactly one reply, either a detection of the latest cloud or at once an
error reply "busy, retry" that names how many queries wait. None is lost and none times out. The
status counts the refused queries exactly, and the service stays healthy and answers again."""

from __future__ import annotations

import time

import numpy as np
import zenoh
from sofia_detector.worker import QUERIES_MAX
from sofia_runtime import client, zenoh_config
from sofia_schemas import Keys
from sofia_schemas.messages import Detection, ErrorReply, ServiceStatus

from .conftest import Service
from .test_memory import _cloud

BURST = 4 * QUERIES_MAX


def _busy_count(session: zenoh.Session, keys: Keys) -> int:
    status = client.ask(session, keys.status("detector"), ServiceStatus, timeout=30)
    return int(status.counters["busy_queries"])


def test_a_burst_of_detect_queries_gets_one_reply_each(detector: Service, module_robot: str) -> None:
    keys = Keys(module_robot)
    with zenoh.open(zenoh_config()) as session:
        session.declare_publisher(keys.points).put(_cloud(np.random.default_rng(1)))
        deadline = time.monotonic() + 30  # the cloud is in: a query without payload answers with it
        while not client.query(session, keys.detect, timeout=10)[0].ok and time.monotonic() < deadline:
            time.sleep(0.2)
        busy_before = _busy_count(session, keys)
        pending = [session.get(keys.detect, timeout=120) for _ in range(BURST)]  # all out before any reply
        replies = [list(p) for p in pending]
        busy_after = _busy_count(session, keys)
        again = client.query(session, keys.detect, timeout=30)
        health = client.ask(session, keys.status("detector"), ServiceStatus, timeout=30)
    assert [len(r) for r in replies] == [1] * BURST, "a query got no reply or several"
    ok = [Detection.model_validate_json(r[0].ok.payload.to_bytes()) for r in replies if r[0].ok is not None]
    errors = [
        ErrorReply.model_validate_json(r[0].err.payload.to_bytes()) for r in replies if r[0].err is not None
    ]
    assert len(ok) + len(errors) == BURST
    assert ok, "no query was served"
    assert errors, (
        f"{BURST} queries at once never filled the queue of {QUERIES_MAX}: the burst tested nothing"
    )
    assert all(e.message.startswith("busy, retry") for e in errors), {e.message for e in errors}
    assert busy_after - busy_before == len(errors), (busy_before, busy_after, len(errors))
    assert again and again[0].ok is not None, "the detector does not answer after the burst"
    assert health.state != "error", health
    assert detector.popen.poll() is None
