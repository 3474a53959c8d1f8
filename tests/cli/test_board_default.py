"""One board default: `sofia up`'s detector, `detector serve`, `viz serve` and `sofia detect`,
each started with no --board in a folder whose config/board.yaml differs from the package's board,
all use that file (each reports the board's digest)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
import uuid
from pathlib import Path

import numpy as np
from sofia_replay.synth import make_scene, render_scene
from sofia_schemas import Board

from ..conftest import SOFIA
from .test_up import free_port


def _status_board(cwd: Path, env: dict[str, str], service: str, robot: str, timeout: float = 90.0) -> str:
    """The board digest in ``service``'s status (asked with `sofia health --json`)."""
    deadline = time.monotonic() + timeout
    last = ""
    while time.monotonic() < deadline:
        r = subprocess.run([SOFIA, "health", service, "--robot", robot, "--json", "--timeout", "2", "--degraded-ok"],
                           cwd=cwd, env=env, capture_output=True, text=True, timeout=60)  # fmt: skip
        last = r.stdout + r.stderr
        if r.returncode == 0:
            return str(json.loads(r.stdout)["info"]["board"])
        time.sleep(0.5)
    raise AssertionError(f"{service} of robot {robot} gave no status: {last}")


def test_every_command_and_service_uses_config_board_without_board_option(tmp_path: Path) -> None:
    cwd = tmp_path / "lab"
    (cwd / "config").mkdir(parents=True)
    (cwd / "config" / "board.yaml").write_text("center: [0.5, 0.0]\nallowed: [[0, 0]]\n")
    want = Board.from_file(cwd / "config" / "board.yaml").digest
    assert want != Board.default().digest
    port = free_port()
    bus = {"SOFIA_ZENOH_MODE": "client", "SOFIA_ZENOH_CONNECT": f"tcp/127.0.0.1:{port}"}
    env = {k: v for k, v in os.environ.items() if k != "SOFIA_BOARD"}
    up_robot, own_robot = f"u{uuid.uuid4().hex[:8]}", f"s{uuid.uuid4().hex[:8]}"
    procs = []
    try:
        procs.append(subprocess.Popen(
            [SOFIA, "up", "--services", "detector", "--robot", up_robot, "--router-listen", f"tcp/127.0.0.1:{port}",
             "--state-dir", str(tmp_path / "state"), "--log-dir", str(tmp_path / "log")],
            cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))  # fmt: skip
        for cmd in (["detector", "serve"], ["viz", "serve", "--port", "0"]):
            procs.append(subprocess.Popen([SOFIA, *cmd, "--robot", own_robot], cwd=cwd, env={**env, **bus},
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))  # fmt: skip
        rng = np.random.default_rng(3)
        cloud = cwd / "scene.npy"
        np.save(cloud, render_scene(make_scene(Board.default(), "one", rng), rng).points_base)
        r = subprocess.run([SOFIA, "detect", str(cloud), "--json"], cwd=cwd, env=env, capture_output=True,
                           text=True, timeout=120)  # fmt: skip
        assert r.returncode == 0, r.stderr
        seen = {"sofia detect": json.loads(r.stdout.splitlines()[0])["board"]}
        seen["sofia up (detector)"] = _status_board(cwd, {**env, **bus}, "detector", up_robot)
        seen["detector serve"] = _status_board(cwd, {**env, **bus}, "detector", own_robot)
        seen["viz serve"] = _status_board(cwd, {**env, **bus}, "viz", own_robot)
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
    assert seen == dict.fromkeys(seen, want), seen
