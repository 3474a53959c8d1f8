"""`sofia up --json`: the health table as one JSON object per change and line, from the real
supervisor with a real router and detector; Ctrl-C stops everything with exit 0."""

from __future__ import annotations

import json
import queue
import signal
import socket
import subprocess
import threading
import time
import uuid
from pathlib import Path

from sofia_system.launcher import sofia_executable

ROOT = Path(__file__).parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_up_json_prints_each_change_of_the_health_table_as_one_json_line(tmp_path: Path) -> None:
    argv = [*sofia_executable(), "up", "--json", "--services", "detector", "--robot", f"up{uuid.uuid4().hex[:8]}",
            "--router-listen", f"tcp/127.0.0.1:{free_port()}", "--state-dir", str(tmp_path / "state"),
            "--log-dir", str(tmp_path / "log")]  # fmt: skip
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    lines: queue.Queue[str] = queue.Queue()
    stdout = proc.stdout
    assert stdout is not None

    def read() -> None:
        for line in stdout:
            lines.put(line)

    threading.Thread(target=read, daemon=True).start()
    tables: list[dict[str, list[dict[str, object]]]] = []
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            try:
                tables.append(json.loads(lines.get(timeout=1.0)))  # every line is one JSON object
            except queue.Empty:
                continue
            if all(r["state"] in ("ok", "running") for r in tables[-1]["services"]):
                break
        else:
            raise AssertionError(f"not healthy within 120 s: {tables[-1:]}")
    finally:
        proc.send_signal(signal.SIGINT)
        rc = proc.wait(60)
    assert rc == 0
    rows = tables[-1]["services"]
    assert [r["service"] for r in rows] == ["router", "detector"]
    assert [r["state"] for r in rows] == ["running", "ok"], rows
    assert all(isinstance(r["pid"], int) and r["restarts"] == 0 for r in rows), rows
    assert tables == [
        t for i, t in enumerate(tables) if i == 0 or t != tables[i - 1]
    ]  # printed on change only
