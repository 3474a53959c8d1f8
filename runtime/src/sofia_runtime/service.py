"""The small shape every SofIA service shares: logging, clean stop, latest-value hand-over, replies.

Zenoh callbacks only hand data over (:class:`LatestSlot`); the work runs on the service's own
thread. Query replies go through :func:`reply_json` and :func:`reply_error`, which also finalise
the query: a query handed to a worker thread stays open until it is dropped, and the querier's
``get`` would otherwise wait for its whole timeout and end with a "Timeout" error.
"""

from __future__ import annotations

import logging
import signal
import subprocess
import threading
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import Generic, Protocol, TypeVar

import zenoh
from pydantic import BaseModel, ValidationError
from sofia_schemas.errors import PayloadError
from sofia_schemas.keys import ENCODING_JSON
from sofia_schemas.messages import ErrorReply, ServiceStatus

from .limits import MESSAGE_CHARS, ClipFilter, check_payload, clip, error_text
from .memory import trim_heap

T = TypeVar("T")
log = logging.getLogger(__name__)
STATUS_PERIOD_S = 1.0


def setup_logging(level: str = "INFO", log_file: str | Path | None = None) -> None:
    """Configure the root logger: ``time level name: message`` to stderr (and a file); every record
    is clipped (:class:`~sofia_runtime.limits.ClipFilter`), so no payload floods a log."""
    handlers: list[logging.Handler] = [logging.StreamHandler()]
    if log_file:
        Path(log_file).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_file))
    for handler in handlers:
        handler.addFilter(ClipFilter())
    logging.basicConfig(
        level=getattr(logging, level.upper(), logging.INFO),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        handlers=handlers,
        force=True,
    )


class StopFlag:
    """A ``threading.Event`` set by SIGINT/SIGTERM (installed when created on the main thread)."""

    def __init__(self) -> None:
        self.event = threading.Event()
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, self._handle)

    def _handle(self, signum: int, _frame: FrameType | None) -> None:
        log.info("received %s, stopping", signal.Signals(signum).name)
        self.event.set()

    def set(self) -> None:
        self.event.set()

    def is_set(self) -> bool:
        return self.event.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        return self.event.wait(timeout)


class LatestSlot(Generic[T]):
    """Holds only the newest ``depth`` items (default 1): ``put`` on a full slot drops the oldest item
    not yet taken and counts it in ``dropped``, so a slow consumer never works on stale data and
    memory stays bounded."""

    def __init__(self, depth: int = 1) -> None:
        if depth < 1:
            raise ValueError(f"LatestSlot depth must be at least 1, got {depth}")
        self._cond = threading.Condition()
        self._items: deque[T] = deque()
        self.depth = depth
        self.dropped = 0
        self.received = 0

    def put(self, item: T) -> None:
        with self._cond:
            if len(self._items) == self.depth:
                self._items.popleft()
                self.dropped += 1
            self._items.append(item)
            self.received += 1
            self._cond.notify()

    def take(self, timeout: float | None = None) -> T | None:
        """The oldest item kept, waiting up to ``timeout`` s; None when nothing arrived."""
        with self._cond:
            if not self._items and not self._cond.wait_for(lambda: bool(self._items), timeout):
                return None
            return self._items.popleft()


def reply_json(query: zenoh.Query, message: BaseModel, key: str | None = None) -> None:
    """Reply to ``query`` with a pydantic message as JSON, then finalise the query."""
    try:
        query.reply(key or str(query.key_expr), message.model_dump_json(), encoding="application/json")
    finally:
        query.drop()


def reply_error(query: zenoh.Query, error: BaseException | str, key: str | None = None) -> None:
    """Reply with an :class:`ErrorReply` saying what was wrong (``reply_err``), then finalise.
    The message is clipped (:func:`~sofia_runtime.limits.error_text`): it quotes at most the first
    characters of an offending value."""
    name = type(error).__name__ if isinstance(error, BaseException) else "Error"
    reply = ErrorReply(error=name, message=error_text(error), key=key or str(query.key_expr))
    try:
        query.reply_err(reply.model_dump_json(), encoding="application/json")
    finally:
        query.drop()


def run_worker(name: str, target: Callable[[], None]) -> threading.Thread:
    """Start ``target`` on a daemon thread named ``name``; exceptions are logged, not swallowed."""

    def wrapped() -> None:
        try:
            target()
        except Exception:
            log.exception("worker %s crashed", name)
            raise

    t = threading.Thread(target=wrapped, name=name, daemon=True)
    t.start()
    return t


def query_payload(query: zenoh.Query) -> bytes:
    """The payload of ``query`` (empty bytes when it has none); :class:`PayloadTooLarge` (a
    ``ValueError``) beyond the limit of its key (:func:`~sofia_runtime.limits.payload_limit`)."""
    check_payload(str(query.key_expr), query.payload)
    return query.payload.to_bytes() if query.payload is not None else b""


M = TypeVar("M", bound=BaseModel)


def stop_child(popen: subprocess.Popen[str], grace_s: float = 5.0) -> None:
    """Stop a child process a service started (an emulator, a simulator): SIGTERM, then SIGKILL
    after ``grace_s``."""
    if popen.poll() is not None:
        return
    popen.terminate()
    try:
        popen.wait(grace_s)
    except subprocess.TimeoutExpired:
        popen.kill()
        popen.wait(5)


def query_message(query: zenoh.Query, model: type[M], what: str) -> M:
    """The JSON ``model`` carried by ``query``; :class:`PayloadError` naming ``what`` (e.g.
    "gripper command") when the query has no payload or it is not a valid ``model``."""
    payload = query_payload(query)
    if not payload:
        raise PayloadError(f"{what} query has no payload: send a JSON {model.__name__}")
    try:
        return model.model_validate_json(payload)
    except ValidationError as e:  # one line: the fields and what was wrong, no pydantic links
        text = bytes(payload).decode("utf-8", errors="replace")
        raise PayloadError(f"{what} {clip(text)} is not a valid {model.__name__}: {error_text(e)}") from None


class StatusEndpoint:
    """A service's status on ``key`` (``Keys.status(name)``): answered when queried (``sofia health``)
    and published by :meth:`publish`, which services call every second.

    ``build`` runs on Zenoh's thread for queries: it must only read the service's state.
    """

    def __init__(self, session: zenoh.Session, key: str, build: Callable[[], ServiceStatus]) -> None:
        self.key = key
        self._build = build
        self._publisher = session.declare_publisher(key, encoding=ENCODING_JSON)
        self._queryable = session.declare_queryable(key, self._answer)

    def _status(self) -> ServiceStatus:
        """The service's status, its detail clipped (an error it quotes may be huge)."""
        status = self._build()
        if len(status.detail) > MESSAGE_CHARS:
            status = status.model_copy(update={"detail": error_text(status.detail)})
        return status

    def _answer(self, query: zenoh.Query) -> None:
        try:
            status = self._status()
        except Exception as e:  # a status that cannot be built is itself news
            log.exception("status of %s", self.key)
            reply_error(query, e, self.key)
            return
        reply_json(query, status, self.key)

    def publish(self) -> None:
        """Publish the status; also hand freed heap memory back to the system (once a second, as
        services call this, the resident size returns to its steady value after any burst)."""
        self._publisher.put(self._status().to_json_bytes(), encoding=ENCODING_JSON)
        trim_heap()

    def undeclare(self) -> None:
        self._queryable.undeclare()
        self._publisher.undeclare()


class Declared(Protocol):
    def undeclare(self) -> None: ...


def serve(
    stop: StopFlag, status: StatusEndpoint, workers: Sequence[threading.Thread], *, name: str,
    log: logging.Logger, declared: Sequence[Declared] = (), on_stop: Sequence[Callable[[], object]] = (),
    also_join: Sequence[threading.Thread] = (), each_period: Sequence[Callable[[], object]] = (),
    join_timeout_s: float = 5.0, period_s: float = STATUS_PERIOD_S,
) -> int:  # fmt: skip
    """The loop a service's ``main`` ends with, inside its session: every ``period_s`` s from the start
    run ``each_period`` and publish ``status``, until ``stop`` is set (SIGINT/SIGTERM) or one of
    ``workers`` ends. Then in order: log "<name> stopping", set ``stop``, run ``on_stop`` (wake the
    workers), join ``workers`` then ``also_join`` (unwatched threads that end on ``stop``, such as
    :func:`~sofia_runtime.client.fetch_latest`'s, out of the session's calls before it closes), each
    within ``join_timeout_s`` s, undeclare ``declared`` in order, then ``status``. Returns 0 ("<name>
    stopped"), or 1 ("<name> worker died, exiting") when a worker ended first: a supervisor restarts it."""
    while True:
        for step in [*each_period, status.publish]:
            step()
        if stop.wait(period_s) or not all(worker.is_alive() for worker in workers):
            break
    crashed = not stop.is_set()
    stop.set()
    log.info("%s stopping", name)
    for step in on_stop:
        step()
    for thread in [*workers, *also_join]:
        thread.join(timeout=join_timeout_s)
    for d in [*declared, status]:
        d.undeclare()
    if crashed:
        log.error("%s worker died, exiting", name)
        return 1
    log.info("%s stopped", name)
    return 0
