"""sofia_runtime.client.query: a query sent before its queryable is reachable is answered once."""

from __future__ import annotations

import subprocess
import sys
import time
import uuid
from pathlib import Path

import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.client import query

QUERYABLE = """
import sys, time, zenoh
from sofia_runtime import zenoh_config
key, count_file = sys.argv[1], sys.argv[2]
time.sleep(1.5)  # the querier starts first
n = 0
def answer(q):
    global n
    n += 1
    open(count_file, "w").write(str(n))
    q.reply(key, b"pong")
with zenoh.open(zenoh_config()) as s:
    s.declare_queryable(key, answer)
    time.sleep(8)
"""


def test_query_waits_for_a_late_queryable_and_sends_once(tmp_path: Path) -> None:
    key = f"sofia/t{uuid.uuid4().hex[:8]}/ping"
    count = tmp_path / "count"
    proc = subprocess.Popen([sys.executable, "-c", QUERYABLE, key, str(count)])
    try:
        with zenoh.open(zenoh_config()) as session:
            t0 = time.monotonic()
            replies = query(session, key, b"ping", timeout=20)
            assert time.monotonic() - t0 >= 1.0  # answered by the late queryable
            assert [r.ok.payload.to_bytes() for r in replies if r.ok is not None] == [b"pong"]
            time.sleep(0.5)
            assert count.read_text() == "1"  # delivered once, not once per retry
    finally:
        proc.kill()
        proc.wait(10)


def test_query_without_queryable_ends_empty_at_the_timeout() -> None:
    with zenoh.open(zenoh_config()) as session:
        t0 = time.monotonic()
        assert query(session, f"sofia/t{uuid.uuid4().hex[:8]}/nobody", timeout=1.0) == []
        assert 0.8 < time.monotonic() - t0 < 5.0


def test_a_stopped_fetch_leaves_the_session_free_to_close() -> None:
    """``fetch_latest`` keeps asking (for up to 30 s) while nobody answers; once its stop is set it
    gives up within a retry, so the service can join it and close its session: a session cannot
    close while another thread is inside one of its calls ("Already borrowed", then an abort)."""
    import threading

    from sofia_runtime.client import fetch_latest

    stop = threading.Event()
    session = zenoh.open(zenoh_config())
    got: list[zenoh.Sample] = []
    thread = fetch_latest(session, f"sofia/t{uuid.uuid4().hex[:8]}/nobody", got.append, stop)
    time.sleep(0.5)
    assert thread.is_alive()  # still asking
    t0 = time.monotonic()
    stop.set()
    thread.join(timeout=5.0)
    assert not thread.is_alive() and time.monotonic() - t0 < 1.0
    session.close()  # nobody inside the session's calls any more
    assert session.is_closed() and got == []
