"""Walking the documented commands that talk to running services, as written: `sofia up` (router,
detector, calibrator and the emulated gripper of robot `panda`, as the docs start it) in the
folder of the offline walk, then every `sofia echo`, `query`, `health`, `gripper` and `replay play`
line of the README and the site's pages in their order, with a recording looping onto the bus as
"Use the bus" says.

A command that returns must exit 0, as the exit-code table says for a job that ran. One
that runs until stopped (`echo` without `--count`, `replay play --loop`, `up`) must still be running
after a while, and exit 0 on Ctrl-C. `echo` must have printed a detection. Left out: the lines that
name hardware (a serial port, a robot IP, a camera serial), the camera's keys and recordings (no
camera here), and `gripper serve` (`sofia up` already serves the gripper); ``ON_THE_BUS`` of
``test_docs_walk.py`` names the tests that run those.
"""

from __future__ import annotations

import contextlib
import os
import queue
import shlex
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest
from sofia_system.launcher import sofia_executable

from .conftest import run_sofia
from .test_docs_walk import sofia_commands

WALKED = [("echo",), ("query",), ("health",), ("gripper",), ("replay", "play")]
HARDWARE = {"--port", "--robot-ip", "--serial"}
UNTIL_STOPPED_S = 2.0  # how long a command that runs until stopped must keep running
STARTED_S = 60.0  # a command that runs until stopped logs its first line within this
FIRST_DETECTION_S = 60.0  # `echo` of the detections: the first one within this


def walked(argv: list[str]) -> bool:
    """True for the documented commands this walk runs (see the module docstring)."""
    if not any(tuple(argv[: len(p)]) == p for p in WALKED) or argv[:2] == ["gripper", "serve"]:
        return False
    if HARDWARE & set(argv) or any("camera" in a for a in argv):
        return False
    return not (argv[:2] == ["replay", "play"] and argv[2] == "out.mcap")  # recorded by `camera record`


def runs_until_stopped(argv: list[str]) -> bool:
    return (argv[0] == "echo" and "--count" not in argv) or (
        argv[:2] == ["replay", "play"] and "--loop" in argv
    )


def start(cwd: Path, env: dict[str, str], *argv: str, log: Path | None = None) -> subprocess.Popen[str]:
    """``sofia ARGV`` in the background: its output through pipes, or into ``log``."""
    out = subprocess.PIPE if log is None else log.open("w")
    return subprocess.Popen([*sofia_executable(), *argv], cwd=cwd, env=env, stdout=out,
                            stderr=out if log else subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip


def run_until_stopped(cwd: Path, env: dict[str, str], argv: list[str], first_line_s: float) -> str | None:
    """Start ``sofia ARGV``; once it has logged that it started, ``UNTIL_STOPPED_S`` later (and, with
    ``first_line_s``, once it has printed a line or that long) Ctrl-C it. Returns what it printed,
    or None when it exited first."""
    proc = start(cwd, env, *argv)
    out: queue.Queue[str] = queue.Queue()
    err: queue.Queue[str] = queue.Queue()
    for stream, q in ((proc.stdout, out), (proc.stderr, err)):
        assert stream is not None
        threading.Thread(target=lambda s=stream, q=q: [q.put(line) for line in s], daemon=True).start()
    with contextlib.suppress(queue.Empty):
        err.get(timeout=STARTED_S)  # its first log line: past the imports, running
    time.sleep(UNTIL_STOPPED_S)
    printed: list[str] = []
    with contextlib.suppress(queue.Empty):
        printed.append(out.get(timeout=first_line_s) if first_line_s else out.get_nowait())
    if proc.poll() is not None:
        return None
    stop(proc, f"sofia {shlex.join(argv)}")
    while not out.empty():
        printed.append(out.get())
    return "".join(printed)


def stop(proc: subprocess.Popen[str], what: str, log: Path | None = None) -> None:
    """Ctrl-C; it must exit 0 within a minute (else it is killed, and the end of ``log`` told)."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=10)
        tail = log.read_text(errors="replace")[-2000:] if log is not None and log.exists() else ""
        raise AssertionError(f"{what}: still running 60 s after Ctrl-C; its log ends:\n{tail}") from None
    tail = log.read_text(errors="replace")[-2000:] if log is not None and log.exists() else ""
    assert proc.returncode == 0, f"{what}: exit {proc.returncode} on Ctrl-C; its log ends:\n{tail}"


ROUTER_PORT = 7447  # `sofia up`'s router, as the docs start it


def wait_port_free(port: int = ROUTER_PORT, timeout: float = 180.0) -> None:
    """Wait until nothing listens on 127.0.0.1:``port`` (another walk's `sofia up` finishing): the
    walk starts `sofia up` as the docs do, on its default port, and must talk to that one only."""
    deadline = time.monotonic() + timeout
    while True:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) != 0:
                return
        assert time.monotonic() < deadline, (
            f"127.0.0.1:{port} stays in use: another `sofia up` runs on this machine"
        )
        time.sleep(1.0)


def wait_healthy(cwd: Path, service: str, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while True:
        r = run_sofia(cwd, "health", service, timeout=60)
        if r.returncode == 0:
            return
        assert time.monotonic() < deadline, f"{service} not healthy under `sofia up`: {r.stdout} {r.stderr}"
        time.sleep(1.0)


@pytest.mark.timeout(900)  # 27 commands, several of which run for seconds, on a shared machine
def test_the_documented_bus_commands_run_as_written_against_sofia_up(walk_dir: Path) -> None:
    commands = [(n, a) for n, a in sofia_commands() if walked(a)]
    assert len(commands) >= 20, commands  # 27 when written
    for _, argv in sofia_commands():  # the files the walked commands read: cloud.cdr, recordings/*.mcap
        if argv[:2] in (["replay", "export"], ["replay", "convert"]):
            r = run_sofia(walk_dir, *argv)
            assert r.returncode == 0, f"sofia {shlex.join(argv)}: {r.stderr[-400:]}"
    # robot panda and the default bus, as a user's shell has them; output unbuffered through the pipes
    env = {k: v for k, v in os.environ.items() if not k.startswith("SOFIA_")} | {"PYTHONUNBUFFERED": "1"}
    wait_port_free()
    up = start(walk_dir, env, "up", log=walk_dir / "up.out")
    failed: list[str] = []
    try:
        for service in ("detector", "calibrator", "gripper"):
            wait_healthy(walk_dir, service)
        loop_log = walk_dir / "loop.out"  # a file, not pipes nobody reads: they could fill and block it
        loop = start(
            walk_dir, env, "replay", "play", "var/recordings/scenes.mcap", "--loop", log=loop_log
        )  # as "Using it" says
        try:
            for n, argv in commands:
                where = f"{n}: sofia {shlex.join(argv)}"
                if runs_until_stopped(argv):
                    out = run_until_stopped(
                        walk_dir, env, argv, FIRST_DETECTION_S if argv[0] == "echo" else 0.0
                    )
                    if out is None:
                        failed.append(f"{where} -> exited before Ctrl-C")
                    elif argv[0] == "echo" and "objects" not in out:
                        failed.append(
                            f"{where} printed no detection within {FIRST_DETECTION_S} s: {out[-400:]!r}"
                        )
                    continue
                r = run_sofia(walk_dir, *argv, timeout=120)
                if r.returncode != 0:
                    failed.append(f"{where} -> exit {r.returncode}: {(r.stderr or r.stdout).strip()[-400:]}")
        finally:
            stop(loop, "replay play --loop", loop_log)
    finally:
        stop(up, "sofia up", walk_dir / "up.out")
    assert not failed, "\n".join(failed)
