"""The calibrator's query deadline, through the running service: with its worker held busy by a
flood of slow solves, every query is answered (ok, or a named "busy, retry") within the deadline
plus the time of the one solve in progress; the busy ones are counted in the status, and the
service answers normally afterwards."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import zenoh
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.online import make_sample
from sofia_calibrator.samples.store import SampleStore
from sofia_schemas.keys import Keys

from ..conftest import query_json

T0_NS = 1_700_000_000_000_000_000
DEADLINE_S = 0.5  # --query-deadline of the service under test (the default is 8 s)
MARGIN_S = 2.0  # the solve in progress when the deadline passes, Zenoh, a loaded machine
WAIT_S = 25.0  # how long the test waits for the replies (long enough to see late ones)
SAMPLES = 2000  # each solve of these takes about 0.1 s: the flood is 15 s of work without a deadline
FLOOD = 150  # solve queries sent at once: more than the 100 the inbox queues


class Replies:
    """Each query's (ok, JSON body, seconds from sending to its first reply)."""

    def __init__(self) -> None:
        self.got: dict[int, tuple[bool, dict, float]] = {}  # type: ignore[type-arg]
        self._lock = threading.Lock()

    def send(self, session: zenoh.Session, key: str, i: int) -> None:
        sent = time.monotonic()

        def on_reply(reply: zenoh.Reply) -> None:  # Zenoh's thread: record the first reply only
            waited = time.monotonic() - sent
            ok = reply.ok is not None
            raw = reply.ok.payload.to_bytes() if reply.ok is not None else reply.err.payload.to_bytes()  # type: ignore[union-attr]
            try:
                body = json.loads(raw)
            except ValueError:
                body = {"raw": raw.decode(errors="replace")}  # Zenoh's own "Timeout"
            with self._lock:
                self.got.setdefault(i, (ok, body, waited))

        session.get(key, handler=on_reply, timeout=WAIT_S)


def test_every_query_is_answered_within_its_deadline_while_the_worker_is_busy(  # type: ignore[no-untyped-def]
    sofia_proc, session, robot_id: str, tmp_path: Path
) -> None:
    keys = Keys(robot_id)
    store = SampleStore(tmp_path / "state")  # samples the service resumes (adding them by query
    pr = make_problem(SAMPLES, np.random.default_rng(3))  # would race the short deadline)
    for k in range(SAMPLES):
        store.add(make_sample(T0_NS + k, pr.p_cam[k], pr.T_base_flange[k]))
    store.close()
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "state"),
                      "--query-deadline", str(DEADLINE_S))  # fmt: skip
    proc.wait_for_log("calibrator ready", timeout=40)
    proc.wait_for_log(f"solved with {SAMPLES} samples", timeout=40)
    ok, body = query_json(session, keys.calibrator_op("result"))
    assert ok and body["n_samples"] == SAMPLES, body

    replies = Replies()
    for i in range(FLOOD):
        replies.send(session, keys.calibrator_op("solve"), i)
    deadline = time.monotonic() + WAIT_S
    while len(replies.got) < FLOOD and time.monotonic() < deadline:
        time.sleep(0.02)

    assert sorted(replies.got) == list(range(FLOOD)), f"{FLOOD - len(replies.got)} queries unanswered"
    late = [w for ok, _, w in replies.got.values() if w > DEADLINE_S + MARGIN_S]
    assert not late, f"{len(late)} replies after {DEADLINE_S + MARGIN_S} s (slowest {max(late):.1f} s)"
    busy: dict[str, int] = {"CalibratorLate": 0, "CalibratorBusy": 0}
    for ok, body, _ in replies.got.values():
        if not ok:
            assert body.get("error") in busy and body["message"].startswith("busy, retry"), body
            busy[body["error"]] += 1
    solved = FLOOD - sum(busy.values())
    assert solved >= 1 and busy["CalibratorLate"] >= 1, (solved, busy)

    ok, status = query_json(session, keys.status("calibrator"))
    counters = status["counters"]
    assert counters["late_queries"] == busy["CalibratorLate"], (counters, busy)
    assert counters["dropped_queries"] == sum(busy.values()), (counters, busy)

    ok, body = query_json(session, keys.calibrator_op("result"), timeout=5)  # serving normally again
    assert ok and body["n_samples"] == SAMPLES, body
    ok, body = query_json(session, keys.calibrator_op("samples"), json.dumps({"limit": 3}), timeout=5)
    assert ok and [s["sample_id"] for s in body["samples"]] == [0, 1, 2], body
    assert proc.stop() == 0
