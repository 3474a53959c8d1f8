"""Shared fixtures and helpers: a unique robot id per test (isolates Zenoh traffic), real service
processes started with the ``sofia`` command (stopped with SIGTERM, their logs kept), a Zenoh session
of the test process, queries (:func:`query_json`, :func:`first_reply` with :func:`reply_ok` /
:func:`reply_err`) and ``collect(key_expr)``, a subscriber that records every sample it hears."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest
import zenoh
from pydantic import BaseModel
from sofia_runtime import client, zenoh_config
from sofia_runtime.zenoh_config import open_session
from sofia_schemas.messages import CalibrationResult, ErrorReply
from sofia_schemas.transforms import matrix_to_quat_xyzw, pose_gap

REPO = Path(__file__).resolve().parents[1]
SOFIA = str(Path(sys.executable).with_name("sofia"))
M = TypeVar("M", bound=BaseModel)


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


def first_reply(session: zenoh.Session, key: str, payload: str | bytes | None = None, timeout: float = 10.0,
                encoding: str | None = None) -> zenoh.Reply:  # fmt: skip
    """The one reply to a query on ``key`` (discovery included, see :func:`sofia_runtime.client.query`);
    fails when there is none or more than one."""
    replies = client.query(session, key, payload, timeout=timeout, encoding=encoding)
    assert len(replies) == 1, f"{len(replies)} replies to {key} within {timeout} s (expected 1)"
    return replies[0]


def reply_ok(reply: zenoh.Reply, model: type[M]) -> M:
    """An ok reply parsed as ``model``; fails with the error reply's text otherwise."""
    assert reply.ok is not None, reply.err.payload.to_bytes() if reply.err is not None else None
    return model.model_validate_json(reply.ok.payload.to_bytes())


def reply_err(reply: zenoh.Reply) -> ErrorReply:
    """An error reply as its :class:`ErrorReply`; fails on an ok reply."""
    assert reply.err is not None, "expected an error reply"
    return ErrorReply.model_validate_json(reply.err.payload.to_bytes())


def gap_mm_deg(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """(translation mm, rotation deg) between two (4, 4) poses (:func:`pose_gap` in test units)."""
    dt, dr = pose_gap(T_est, T_true)
    return 1e3 * dt, float(np.degrees(dr))


def calibration_result(T_flange_cam: np.ndarray, stamp_ns: int = 7, **fields: Any) -> CalibrationResult:
    """A passing calibrator result holding ``T_flange_cam`` (4, 4), flange -> camera optical frame,
    metres; ``fields`` replace the others (``target_base``, ``camera_correction``, ...)."""
    T = np.asarray(T_flange_cam, dtype=np.float64)
    values: dict[str, Any] = dict(
        stamp_ns=stamp_ns, matrix=T.tolist(), translation=tuple(T[:3, 3]),
        quaternion_xyzw=tuple(matrix_to_quat_xyzw(T[:3, :3])), rpy=(0.0, 0.0, 0.0), target_base=(0.5, 0.0, 0.1),
        spread_mm=(1.0, 1.0, 1.0), passes=True, n_samples=12, inliers=list(range(12)), outliers=[],
        residuals_mm=[0.5] * 12, std_translation_mm=(0.1, 0.1, 0.1), std_rotation_deg=(0.01, 0.01, 0.01),
        dissipation_after=0.1,
    )  # fmt: skip
    return CalibrationResult(**(values | fields))


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

    def models(self, key: str, model: type[M]) -> list[M]:
        """The JSON payloads on ``key`` so far, as ``model``."""
        return [model.model_validate_json(s.payload) for s in self.on(key)]

    def clear(self) -> None:
        with self._lock:
            self.samples.clear()

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
