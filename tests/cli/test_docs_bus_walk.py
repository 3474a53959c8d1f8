"""Walking the documented commands that talk to running services, as written: `sofia up` (router,
detector, calibrator and the emulated gripper of robot `panda`, as the docs start it) in the
folder of the offline walk, then every `sofia echo`, `query`, `health`, `gripper` and `replay play`
line of the README and the site's pages in their order, with a recording looping onto the bus as
"Use the bus" says. A command given again on another page runs once. The commands run in
``LANES`` lanes at once, as commands typed in several terminals: the gripper's in one lane in the
docs' order (each changes the gripper's state), every other command on its own.

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
import re
import shlex
import signal
import socket
import subprocess
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from sofia_system.launcher import sofia_executable

from .conftest import run_once, run_sofia
from .test_docs_walk import sofia_commands

WALKED = [("echo",), ("query",), ("health",), ("gripper",), ("replay", "play")]
HARDWARE = {"--port", "--robot-ip", "--serial"}
UNTIL_STOPPED_S = 2.0  # how long a command that runs until stopped must keep running
STARTED_S = 60.0  # a command that runs until stopped logs its first line within this
FIRST_DETECTION_S = 60.0  # `echo` of the detections: the first one within this
LANES = 3  # commands running at once (2 cores: most of a lane's time is a process starting or waiting)


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


_ROW = re.compile(r"^(\S+)\s+(?:\d+|-)\s+(.+?)\s+\d+$")  # a row of `sofia up`'s health table


def up_states(log: Path) -> dict[str, str]:
    """service -> state of the last health table `sofia up` printed into ``log`` (empty before one)."""
    states: dict[str, str] = {}
    for line in log.read_text(errors="replace").splitlines() if log.exists() else []:
        if line.split()[:2] == ["service", "pid"]:
            states = {}
        elif m := _ROW.match(line.strip()):
            states[m[1]] = m[2]
    return states


def wait_healthy(log: Path, services: tuple[str, ...], timeout: float = 120.0) -> None:
    """Wait until the health table of the `sofia up` writing ``log`` shows each of ``services`` ok
    (the state `sofia health SERVICE` exits 0 on; `sofia up` asks every second)."""
    deadline = time.monotonic() + timeout
    while not all(up_states(log).get(s) == "ok" for s in services):
        assert time.monotonic() < deadline, (
            f"{services} not all ok under `sofia up` in {timeout} s: {up_states(log)}; its log ends:\n"
            + log.read_text(errors="replace")[-2000:]
        )
        time.sleep(0.2)


def lanes(commands: list[tuple[str, list[str]]]) -> list[list[tuple[str, list[str]]]]:
    """``commands`` (``page:line``, argv), each once, in lanes that may run at the same time: the
    gripper's in one lane in their order, every other command in a lane of its own."""
    once = list({tuple(a): (n, a) for n, a in reversed(commands)}.values())[::-1]  # first of each
    gripper = [(n, a) for n, a in once if a[0] == "gripper"]
    return [gripper, *([c] for c in once if c[1][0] != "gripper")]


def run_lane(cwd: Path, env: dict[str, str], lane: list[tuple[str, list[str]]]) -> list[str]:
    """Run the commands of ``lane`` one after the other; what failed, one line each."""
    failed = []
    for n, argv in lane:
        where = f"{n}: sofia {shlex.join(argv)}"
        if runs_until_stopped(argv):
            out = run_until_stopped(cwd, env, argv, FIRST_DETECTION_S if argv[0] == "echo" else 0.0)
            if out is None:
                failed.append(f"{where} -> exited before Ctrl-C")
            elif argv[0] == "echo" and "objects" not in out:
                failed.append(f"{where} printed no detection within {FIRST_DETECTION_S} s: {out[-400:]!r}")
            continue
        r = run_sofia(cwd, *argv, timeout=120)
        if r.returncode != 0:
            failed.append(f"{where} -> exit {r.returncode}: {(r.stderr or r.stdout).strip()[-400:]}")
    return failed


def test_up_states_reads_the_last_health_table(tmp_path: Path) -> None:
    log = tmp_path / "up.out"
    assert up_states(log) == {}
    header = "service          pid  state       restarts\n"
    log.write_text(
        header
        + "router         101  running            0\ndetector       102  no status          0\n"
        + "12:00:01 INFO started gripper\n"
        + header
        + "detector       102  ok                 1\ngripper          -  error              2\n"
    )
    assert up_states(log) == {"detector": "ok", "gripper": "error"}


def test_lanes_run_each_command_once_and_the_gripper_in_order() -> None:
    open_, stop_ = ["gripper", "open"], ["gripper", "stop"]
    query, health = ["query", "k"], ["health", "detector"]
    commands = [
        ("a:1", open_),
        ("a:2", query),
        ("b:1", open_),
        ("b:2", stop_),
        ("b:3", query),
        ("b:4", health),
    ]
    assert lanes(commands) == [[("a:1", open_), ("b:2", stop_)], [("a:2", query)], [("b:4", health)]]


@pytest.mark.timeout(600)  # 22 distinct commands, several of which run for seconds, on a shared machine
def test_the_documented_bus_commands_run_as_written_against_sofia_up(walk_dir: Path) -> None:
    commands = [(n, a) for n, a in sofia_commands() if walked(a)]
    assert len(commands) >= 20, commands  # 27 when written
    for _, argv in sofia_commands():  # the files the walked commands read: cloud.cdr, recordings/*.mcap
        if argv[:2] in (["replay", "export"], ["replay", "convert"]):
            r = run_once(walk_dir, *argv)
            assert r.returncode == 0, f"sofia {shlex.join(argv)}: {r.stderr[-400:]}"
    # robot panda and the default bus, as a user's shell has them; output unbuffered through the pipes
    env = {k: v for k, v in os.environ.items() if not k.startswith("SOFIA_")} | {"PYTHONUNBUFFERED": "1"}
    wait_port_free()
    up = start(walk_dir, env, "up", log=walk_dir / "up.out")
    try:
        wait_healthy(walk_dir / "up.out", ("detector", "calibrator", "gripper"))
        loop_log = walk_dir / "loop.out"  # a file, not pipes nobody reads: they could fill and block it
        loop = start(
            walk_dir, env, "replay", "play", "var/recordings/scenes.mcap", "--loop", log=loop_log
        )  # as "Using it" says
        try:
            # as a user reads the docs: the recording is playing (a detection is out) before the
            # commands that ask for the latest cloud run
            first = run_sofia(walk_dir, "echo", "sofia/panda/detector/detections", "--count", "1",
                              "--timeout", str(FIRST_DETECTION_S), timeout=2 * FIRST_DETECTION_S)  # fmt: skip
            assert first.returncode == 0 and "objects" in first.stdout, (
                f"no detection within {FIRST_DETECTION_S} s of `replay play --loop`: {first.stderr[-400:]}; "
                f"its log ends:\n{loop_log.read_text(errors='replace')[-1000:]}"
            )
            with ThreadPoolExecutor(LANES) as pool:
                failed = [f for lane in pool.map(lambda ln: run_lane(walk_dir, env, ln), lanes(commands))
                          for f in lane]  # fmt: skip
        finally:
            stop(loop, "replay play --loop", loop_log)
    finally:
        stop(up, "sofia up", walk_dir / "up.out")
    assert not failed, "\n".join(failed)
