"""Fixtures: an MX-64 emulator on a real pty, and the driver talking to it through dynamixel_sdk."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from dynamixel_sdk import PortHandler
from sofia_gripper import Emulator, Gripper, GripperConfig
from sofia_gripper.bus import MarginPort
from sofia_gripper.service import EMULATED_REPLY_MARGIN_MS
from sofia_schemas.messages import GripperState

BAUD = 1_000_000


def wait_until(predicate: Callable[[], bool], timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.01)
    raise AssertionError(f"not reached within {timeout} s: {what}")


def make_config(path: str, protocol: int = 2, **kw: object) -> GripperConfig:
    """The emulated servo's config; replies waited for as the service waits for an emulator's (a
    process on this host, which a loaded host delays beyond the SDK's timeout for a real adapter)."""
    base = {"port": path, "baud": BAUD, "protocol": protocol, "reconnect_period_s": 0.2, "watchdog_ms": 200,
            "reply_margin_ms": EMULATED_REPLY_MARGIN_MS}  # fmt: skip
    return GripperConfig.model_validate({**base, **kw})


@pytest.fixture
def emulator(tmp_path: Path) -> Iterator[Emulator]:
    with Emulator(protocol=2, baud=BAUD, link_path=tmp_path / "ttyDXL") as emu:
        yield emu


def open_port(path: str) -> PortHandler:
    """``path`` opened with the real dynamixel_sdk, its status-packet timeouts lengthened as the
    service's for an emulator, for packet-level tests."""
    p = MarginPort(path)
    p.margin_ms = EMULATED_REPLY_MARGIN_MS
    assert p.setBaudRate(BAUD)
    return p


@pytest.fixture
def port(emulator: Emulator) -> Iterator[PortHandler]:
    p = open_port(emulator.path)
    yield p
    p.closePort()


@pytest.fixture
def emulator_p1(tmp_path: Path) -> Iterator[Emulator]:
    with Emulator(protocol=1, baud=BAUD, link_path=tmp_path / "ttyDXL1") as emu:
        yield emu


@contextmanager
def connected(config: GripperConfig, **kwargs: Any) -> Iterator[Gripper]:
    """A started :class:`Gripper` once it is connected; closed on leaving."""
    g = Gripper(config, **kwargs)
    g.start()
    try:
        wait_until(lambda: g.state.connected, 3.0, "gripper connected")
        yield g
    finally:
        g.close()


@pytest.fixture
def overloaded_p1(emulator_p1: Emulator) -> Iterator[Gripper]:
    """A Protocol 1.0 gripper, connected, then in the error state of an overload of its servo."""
    with connected(make_config(emulator_p1.path, protocol=1)) as g:
        emulator_p1.inject_overload()
        wait_until(lambda: g.state.status == "error", 2.0, "P1 error state")
        yield g


class StateLog:
    def __init__(self) -> None:
        self.states: list[GripperState] = []

    def __call__(self, state: GripperState) -> None:
        self.states.append(state)


@pytest.fixture
def gripper(emulator: Emulator) -> Iterator[Gripper]:
    with connected(make_config(emulator.path), on_state=StateLog()) as g:
        yield g
