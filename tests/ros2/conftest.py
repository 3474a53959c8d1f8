"""A Zenoh router on a free port (where rmw_zenoh nodes would find it), SofIA's processes as its
clients, and the zenoh-ros2-sdk peer as a separate process."""

from __future__ import annotations

import json
import queue
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from sofia_schemas.ros2.typesupport import MSGS_DIR

PEER = Path(__file__).with_name("peer.py")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_port(port: int, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise AssertionError(f"nothing listens on 127.0.0.1:{port} after {timeout} s")


@dataclass
class Bus:
    port: int
    env: dict[str, str]  # makes a sofia process a client of the router


@pytest.fixture
def bus(sofia_proc: Callable[..., Any]) -> Bus:
    port = free_port()
    sofia_proc("router", "--listen", f"tcp/127.0.0.1:{port}")
    wait_port(port)
    return Bus(port, {"SOFIA_ZENOH_MODE": "client", "SOFIA_ZENOH_CONNECT": f"tcp/127.0.0.1:{port}"})


class Peer:
    """The zenoh-ros2-sdk peer process; its JSON lines arrive in ``lines``."""

    def __init__(self, args: list[str], log_path: Path) -> None:
        self._log = open(log_path, "wb")
        self.log_path = log_path
        self.popen = subprocess.Popen(
            [sys.executable, str(PEER), *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=self._log,
        )  # fmt: skip
        self.lines: queue.Queue[dict[str, Any]] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.popen.stdout is not None
        for raw in self.popen.stdout:
            if raw.strip().startswith(b"{"):
                self.lines.put(json.loads(raw))

    def next(self, key: str, timeout: float = 30.0) -> Any:
        """The next line carrying ``key`` (lines without it are skipped and lost)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            if key in line:
                return line[key]
        raise AssertionError(f"peer printed no {key!r} in {timeout} s; its log:\n{self.log_path.read_text()}")

    def stop(self) -> None:
        if self.popen.poll() is None:
            assert self.popen.stdin is not None
            self.popen.stdin.close()
            try:
                self.popen.wait(10)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(5)
        self._log.close()


@pytest.fixture
def peer(tmp_path: Path, bus: Bus, robot_id: str) -> Iterator[Callable[..., Peer]]:
    peers: list[Peer] = []

    def start(*args: str) -> Peer:
        p = Peer(["--port", str(bus.port), "--robot", robot_id, "--msgs", str(MSGS_DIR), *args],
                 tmp_path / f"peer{len(peers)}.log")  # fmt: skip
        peers.append(p)
        return p

    yield start
    for p in peers:
        p.stop()
