"""A Zenoh subscriber in the test process that records every sample it hears."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest
import zenoh
from sofia_runtime.zenoh_config import open_session


@dataclass(frozen=True)
class Received:
    key: str
    payload: bytes
    encoding: str
    t: float  # time.monotonic() at arrival


class Collector:
    def __init__(self) -> None:
        self.samples: list[Received] = []
        self._lock = threading.Lock()

    def __call__(self, sample: zenoh.Sample) -> None:
        r = Received(str(sample.key_expr), sample.payload.to_bytes(), str(sample.encoding), time.monotonic())
        with self._lock:
            self.samples.append(r)

    def on(self, key: str) -> list[Received]:
        with self._lock:
            return [s for s in self.samples if s.key == key]

    def wait_for(self, key: str, n: int, timeout: float = 30.0) -> list[Received]:
        """Samples on ``key`` once there are ``n`` (or all there are after ``timeout``)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and len(self.on(key)) < n:
            time.sleep(0.02)
        return self.on(key)


@pytest.fixture
def collect() -> Iterator[Callable[[str], Collector]]:
    """``collect(key_expr)`` subscribes (in this process) and returns the growing sample list."""
    session = open_session()
    subs = []

    def start(key_expr: str) -> Collector:
        c = Collector()
        subs.append(session.declare_subscriber(key_expr, c))
        return c

    yield start
    for s in subs:
        s.undeclare()
    session.close()
