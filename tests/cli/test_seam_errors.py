"""Errors where SofIA meets the user: one line naming what was wrong, the documented exit code."""

from __future__ import annotations

import os
import subprocess
import time
import uuid
from pathlib import Path

import pytest
from sofia_runtime import cli

from ..conftest import SOFIA
from ..ros2.conftest import wait_port
from .test_up import free_port


def _run(
    *args: str, env: dict[str, str] | None = None, timeout: float = 120
) -> subprocess.CompletedProcess[str]:
    return subprocess.run([SOFIA, *args], capture_output=True, text=True, timeout=timeout, env=env)


def test_busy_router_port_one_line_exit_2_and_up_stops(tmp_path: Path) -> None:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    first = subprocess.Popen([SOFIA, "router", "--listen", endpoint], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)  # fmt: skip
    try:
        wait_port(port)
        r = _run("router", "--listen", endpoint)
        assert r.returncode == 2, r.stderr
        assert (
            r.stderr
            == f"sofia router: error: cannot listen on {endpoint}: address already in use (os error 98)\n"
        )
        # a client of that router asking a key nobody serves: told so, not shown Zenoh's "Timeout" bytes
        env = dict(os.environ, SOFIA_ZENOH_MODE="client", SOFIA_ZENOH_CONNECT=endpoint)
        q = _run("query", f"sofia/q{uuid.uuid4().hex[:8]}/nobody", "--timeout", "1", env=env)
        assert (
            q.returncode == 1 and q.stdout == "" and "no reply from" in q.stderr and "hex" not in q.stderr
        ), q
        # sofia up with its router on the taken port: one line, exit 2, no restart loop
        t0 = time.monotonic()
        up = _run("up", "--services", "detector", "--robot", f"b{uuid.uuid4().hex[:8]}", "--router-listen", endpoint,
                  "--state-dir", str(tmp_path / "state"), "--log-dir", str(tmp_path / "log"), timeout=90)  # fmt: skip
        assert up.returncode == 2, (up.stdout, up.stderr)
        errors = [line for line in up.stderr.splitlines() if line.startswith("sofia up:")]
        assert errors == [f"sofia up: error: the router did not start: sofia router: error: cannot listen on "
                          f"{endpoint}: address already in use (os error 98)"], up.stderr  # fmt: skip
        assert "Traceback" not in up.stderr and time.monotonic() - t0 < 60
    finally:
        first.terminate()
        first.wait(10)


@pytest.mark.parametrize(
    ("head", "why"),
    [
        (b"hello world, not a recording", "it does not start with the MCAP magic bytes"),
        (b"#ROSBAG V2.0\n", "a ROS 1 bag (`sofia replay convert` turns it into MCAP)"),
        (b"\x89MCAP0\r\n", "it ends early (8 bytes): truncated or still being written"),
    ],
)
def test_mcap_errors_say_what_the_file_is(
    head: bytes, why: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], root_logging: None
) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(head)
    for argv in (["replay", "info", str(path)], ["detect", str(path)]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is not a readable MCAP file: " + why in err, err
        assert "(104, " not in err and "Errno" not in err
