"""Queries from scripts and tools: wait until a queryable is reachable, then ask once.

A process that has just opened its session may not have discovered its peers yet; a query sent
at once would find no queryable and end empty. A Zenoh ``Querier`` knows when a queryable matches.
"""

from __future__ import annotations

import time

import zenoh

POLL_S = 0.02


def query(
    session: zenoh.Session,
    key: str,
    payload: bytes | str | None = None,
    timeout: float = 10.0,
    encoding: str | None = None,
) -> list[zenoh.Reply]:
    """Every reply to one query on ``key``, sent as soon as a queryable matches (at most ``timeout``
    seconds for discovery and replies together); an empty list when no queryable answers."""
    deadline = time.monotonic() + timeout
    querier = session.declare_querier(key, timeout=timeout)
    try:
        while not querier.matching_status and time.monotonic() < deadline:
            time.sleep(POLL_S)
        remaining = max(0.1, deadline - time.monotonic())
        if not querier.matching_status:
            return []
        replies = session.get(key, payload=payload, encoding=encoding, timeout=remaining)
        return list(replies)
    finally:
        querier.undeclare()
