"""What the calibrator's Zenoh callbacks hand to its worker, in three bounded queues.

Queries have their own queue (a flood of blobs never crowds them out); when it is full the caller
answers "busy, retry" at once. Poses and blobs finding theirs full are dropped and counted per
kind; camera clouds keep the newest few. The worker takes everything pending at once.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

QUERY_DEADLINE_S = 8.0  # default: a query the worker reaches later is answered "busy, retry"


@dataclass
class Batch:
    """Everything pending when the worker woke up, oldest first."""

    events: list[tuple[str, bytes]] = field(default_factory=list)  # ("pose" | "blob", payload)
    clouds: list[bytes] = field(default_factory=list)
    queries: list[tuple[str, Any, float]] = field(default_factory=list)  # (op, zenoh.Query, arrival)

    def __bool__(self) -> bool:
        return bool(self.events or self.clouds or self.queries)


class Inbox:
    def __init__(self, events_max: int, clouds_max: int, queries_max: int) -> None:
        self._cond = threading.Condition()
        self._events: deque[tuple[str, bytes]] = deque()
        self._clouds: deque[bytes] = deque()
        self._queries: deque[tuple[str, Any, float]] = deque()
        self.events_max, self.clouds_max, self.queries_max = events_max, clouds_max, queries_max
        self.dropped = {"pose": 0, "blob": 0, "cloud": 0}
        self.busy = 0  # queries answered "busy, retry" instead of queued

    def put_event(self, kind: str, payload: bytes) -> None:
        with self._cond:
            if len(self._events) >= self.events_max:
                self.dropped[kind] += 1
                return
            self._events.append((kind, payload))
            self._cond.notify()

    def put_cloud(self, payload: bytes) -> None:
        with self._cond:
            if len(self._clouds) >= self.clouds_max:
                self._clouds.popleft()
                self.dropped["cloud"] += 1
            self._clouds.append(payload)
            self._cond.notify()

    def put_query(self, op: str, query: Any) -> int:
        """Queue a query; returns 0, or the number waiting when the queue is full (not queued)."""
        with self._cond:
            if len(self._queries) >= self.queries_max:
                self.busy += 1
                return len(self._queries)
            self._queries.append((op, query, time.monotonic()))
            self._cond.notify()
            return 0

    def take(self, timeout: float) -> Batch:
        """Everything pending, waiting up to ``timeout`` s for something to arrive."""
        with self._cond:
            self._cond.wait_for(lambda: bool(self._events or self._clouds or self._queries), timeout)
            batch = Batch(list(self._events), list(self._clouds), list(self._queries))
            self._events.clear()
            self._clouds.clear()
            self._queries.clear()
            return batch
