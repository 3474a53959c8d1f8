"""Shared fixtures: a unique robot id per test (isolates Zenoh traffic), real service processes
started with the ``sofia`` command (stopped with SIGTERM, their logs kept), a Zenoh session of the
test process, and :func:`query_json` for the JSON replies of a queryable."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh
from sofia_runtime import client, zenoh_config

REPO = Path(__file__).resolve().parents[1]
SOFIA = str(Path(sys.executable).with_name("sofia"))


@pytest.fixture
def session() -> Iterator[zenoh.Session]:
    """A Zenoh session of the test process, as a client of the services under test."""
    with zenoh.open(zenoh_config()) as s:
        yield s


def query_json(session: zenoh.Session, key: str, payload: str | bytes | None = None,
               timeout: float = 30.0) -> tuple[bool, dict]:  # type: ignore[type-arg]  # fmt: skip
    """(ok, JSON body) of the first reply to a query on ``key`` (an error reply: False and its
    ErrorReply); fails when nothing answers within ``timeout`` (discovery included)."""
    replies = client.query(session, key, payload, timeout=timeout)
    assert replies, f"no reply to {key} within {timeout} s"
    ok, err = replies[0].ok, replies[0].err
    body = ok.payload.to_bytes() if ok is not None else err.payload.to_bytes() if err is not None else b"{}"
    return ok is not None, json.loads(body)


@pytest.fixture
def robot_id() -> str:
    """A robot id no other test uses, so each test has its own key space."""
    return "t" + uuid.uuid4().hex[:10]


class Proc:
    """A ``sofia`` subprocess, in a process group of its own (with the emulator or simulator it
    starts), whose output goes to a log file. Every one is stopped at the end of the run, whatever
    happened to the test that started it."""

    started: list[Proc] = []

    def __init__(self, args: list[str], log_path: Path, env: dict[str, str]) -> None:
        self.args = args
        self.log_path = log_path
        self._log = open(log_path, "wb")
        self.popen = subprocess.Popen(
            [SOFIA, *args], stdout=self._log, stderr=subprocess.STDOUT, env=env, cwd=REPO,
            start_new_session=True,
        )  # fmt: skip
        Proc.started.append(self)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_for_log(self, text: str, timeout: float = 30.0) -> None:
        """Wait until ``text`` appears in the log; fail with the log if the process dies first."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.log():
                return
            if self.popen.poll() is not None:
                raise AssertionError(
                    f"sofia {' '.join(self.args)} exited {self.popen.returncode}:\n{self.log()}"
                )
            time.sleep(0.05)
        raise AssertionError(
            f"{text!r} not in log of sofia {' '.join(self.args)} after {timeout}s:\n{self.log()}"
        )

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 10.0) -> int:
        if self.popen.poll() is None:
            self.popen.send_signal(sig)
            try:
                self.popen.wait(timeout)
            except subprocess.TimeoutExpired:
                self._kill_group()
                self.popen.wait(5)
        self._kill_group()  # whatever of its group outlived it (an emulator, a simulator)
        self._log.close()
        return int(self.popen.returncode)

    def _kill_group(self) -> None:
        try:
            os.killpg(self.popen.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass

    def kill(self) -> None:
        """Kill hard (a crash), no clean shutdown."""
        self.stop(signal.SIGKILL)


@pytest.fixture
def flange_cam_file(tmp_path: Path) -> Path:
    """The synthetic recordings' true T_flange_cam as a ``--transform`` JSON file."""
    from sofia_replay.synth import DEFAULT_T_FLANGE_CAM

    path = tmp_path / "T_flange_cam.json"
    path.write_text(json.dumps({"matrix": DEFAULT_T_FLANGE_CAM.tolist()}))
    return path


@pytest.fixture
def sofia_proc(tmp_path: Path, robot_id: str) -> Iterator[Callable[..., Proc]]:
    """Start ``sofia ARGS...`` as a separate process with ``SOFIA_ROBOT`` set to this test's id."""
    procs: list[Proc] = []

    def start(*args: str, env: dict[str, str] | None = None) -> Proc:
        e = dict(os.environ, SOFIA_ROBOT=robot_id, PYTHONUNBUFFERED="1")
        e.update(env or {})
        p = Proc(list(args), tmp_path / f"proc{len(procs)}-{args[0]}.log", e)
        procs.append(p)
        return p

    yield start
    for p in reversed(procs):
        try:
            p.stop()
        except (OSError, subprocess.SubprocessError):
            p._kill_group()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """No process of the run outlives it."""
    for p in Proc.started:
        if p.popen.poll() is None:
            p._kill_group()


def json_lines(text: str) -> list[dict[str, object]]:
    """Parse every line of ``text`` that is a JSON object."""
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("{"):
            out.append(json.loads(line))
    return out
