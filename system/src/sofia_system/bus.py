"""Small synchronous helpers for talking to the running services from a script."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Generic, TypeVar

import zenoh
from pydantic import BaseModel

M = TypeVar("M", bound=BaseModel)


def wait_until(predicate: Callable[[], bool], timeout: float, interval: float = 0.2) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return predicate()


class Collector(Generic[M]):
    """Collects parsed messages arriving on a key (the callback only appends)."""

    def __init__(self, session: zenoh.Session, key: str, model: type[M],
                 on_message: Callable[[M], None] | None = None) -> None:  # fmt: skip
        self.items: list[M] = []
        self.bad = 0
        self._lock = threading.Lock()
        self._model = model
        self._on_message = on_message
        self._sub = session.declare_subscriber(key, self._callback)

    def _callback(self, sample: zenoh.Sample) -> None:
        try:
            msg = self._model.model_validate_json(sample.payload.to_bytes())
        except ValueError:
            self.bad += 1
            return
        with self._lock:
            self.items.append(msg)
        if self._on_message:
            self._on_message(msg)

    def __len__(self) -> int:
        with self._lock:
            return len(self.items)

    def close(self) -> None:
        self._sub.undeclare()
