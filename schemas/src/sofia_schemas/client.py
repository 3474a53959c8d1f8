"""Queries from scripts and tools, robust to a session that has just been opened.

Right after a session opens, its peers may not be discovered yet and a query finds no queryable:
it ends at once with no reply. Every SofIA queryable answers each query it receives (a result or an
error reply), so an empty answer means the query reached nobody and sending it again cannot run
anything twice; :func:`query` does that until a reply comes or the time is up.
"""

from __future__ import annotations

import time

import zenoh

RETRY_S = 0.1


def query(
    session: zenoh.Session,
    key: str,
    payload: bytes | str | None = None,
    timeout: float = 10.0,
    encoding: str | None = None,
) -> list[zenoh.Reply]:
    """Every reply to a query on ``key`` (at most ``timeout`` seconds for discovery and replies
    together); an empty list when no queryable answered."""
    deadline = time.monotonic() + timeout
    while True:
        remaining = deadline - time.monotonic()
        replies = list(session.get(key, payload=payload, encoding=encoding, timeout=max(0.1, remaining)))
        if replies or time.monotonic() + RETRY_S >= deadline:
            return replies
        time.sleep(RETRY_S)
