"""Queries from scripts and tools, robust to a session that has just been opened.

Right after a session opens, its peers may not be discovered yet and a query finds no queryable:
it ends at once with no reply. Every SofIA queryable answers each query it receives (a result or an
error reply), so an empty answer means the query reached nobody and sending it again cannot run
anything twice; :func:`query` does that until a reply comes or the time is up.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

import zenoh
from pydantic import BaseModel
from sofia_schemas.messages import ErrorReply

RETRY_S = 0.1
M = TypeVar("M", bound=BaseModel)
log = logging.getLogger(__name__)


def matched(publisher: zenoh.Publisher) -> bool:
    """Whether a subscriber of ``publisher``'s key is known (and connected): its
    ``matching_status.matching``. The ``MatchingStatus`` object itself is always true (and
    zenoh-python's type stubs call it a bool)."""
    status: Any = publisher.matching_status
    return bool(status.matching)


class QueryError(RuntimeError):
    """A query got an error reply, or no reply at all."""


def query(
    session: zenoh.Session,
    key: str,
    payload: bytes | str | None = None,
    timeout: float = 10.0,
    encoding: str | None = None,
    stop: threading.Event | None = None,
) -> list[zenoh.Reply]:
    """Every reply to a query on ``key`` (at most ``timeout`` seconds for discovery and replies
    together); an empty list when no queryable answered, or once ``stop`` is set."""
    deadline = time.monotonic() + timeout
    stop = stop or threading.Event()
    while True:
        remaining = deadline - time.monotonic()
        replies = list(session.get(key, payload=payload, encoding=encoding, timeout=max(0.1, remaining)))
        if replies or time.monotonic() + RETRY_S >= deadline or stop.wait(RETRY_S):
            return replies


def is_timeout(err: zenoh.Sample | Any) -> bool:
    """Whether an error reply is Zenoh's own query timeout (payload ``Timeout``), not a service's."""
    return bytes(err.payload.to_bytes()) == b"Timeout"


def ask(session: zenoh.Session, key: str, model: type[M], payload: bytes | str | None = None,
        timeout: float = 10.0) -> M:  # fmt: skip
    """The first reply to a query on ``key`` parsed as ``model``; QueryError naming the error reply
    (its :class:`ErrorReply`) or the silence."""
    for reply in query(session, key, payload, timeout):
        if reply.ok is not None:
            return model.model_validate_json(reply.ok.payload.to_bytes())
        if reply.err is not None and is_timeout(reply.err):
            continue
        raw = reply.err.payload.to_bytes() if reply.err is not None else b""
        try:
            err = ErrorReply.model_validate_json(raw)
        except ValueError:
            raise QueryError(f"{key}: error reply {raw[:200]!r}") from None
        raise QueryError(f"{key}: {err.error}: {err.message}")
    raise QueryError(f"{key}: no reply within {timeout} s")


def fetch_latest(
    session: zenoh.Session,
    key: str,
    on_sample: Callable[[zenoh.Sample], None],
    stop: threading.Event,
    timeout: float = 30.0,
) -> threading.Thread:
    """Ask the queryable of a put + queryable ``key`` (e.g. the calibrator's result) once, in the
    background, for the value published before this process subscribed; each ok reply goes to
    ``on_sample``, as a sample from the subscriber would. Returns the (daemon) thread, which gives
    up once ``stop`` is set: join it before the session closes (a session cannot close while
    another thread is inside one of its calls: zenoh-python raises "Already borrowed", the session
    stays open and the process aborts as it exits)."""

    def run() -> None:
        try:
            for reply in query(session, key, timeout=timeout, stop=stop):
                if reply.ok is not None:
                    on_sample(reply.ok)
        except (zenoh.ZError, RuntimeError) as e:  # the session closed first (or while it was closing)
            log.debug("latest value of %s not fetched: %s", key, e)

    thread = threading.Thread(target=run, name=f"fetch {key}", daemon=True)
    thread.start()
    return thread
