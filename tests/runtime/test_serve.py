"""sofia_runtime.serve.serve: a service process publishes its status until SIGTERM or until its worker
dies, stops in a fixed order, and exits 0 (stopped) or 1 (worker died, so a supervisor restarts it)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from sofia_schemas.keys import Keys
from sofia_schemas.messages import ServiceStatus

from ..conftest import Collector

SERVICE = """
import logging, sys, threading, zenoh
from sofia_runtime.service import serve
from sofia_runtime.service import StatusEndpoint, StopFlag, run_worker, setup_logging
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ServiceStatus, now_ns

robot, crash_after_s = sys.argv[1], float(sys.argv[2])
setup_logging()
log = logging.getLogger("sofia.demo")
stop = StopFlag()
woken = threading.Event()

class Release:
    def undeclare(self):
        log.info("step: release")

def work():
    if crash_after_s > 0:
        woken.wait(crash_after_s)
        raise RuntimeError("demo worker failed")
    woken.wait()
    log.info("step: worker ended")

with zenoh.open(zenoh_config()) as session:
    status = StatusEndpoint(session, Keys(robot).status("demo"),
                            lambda: ServiceStatus(service="demo", stamp_ns=now_ns()))
    worker = run_worker("demo", work)
    log.info("demo ready")
    code = serve(stop, status, [worker], name="demo", log=log, period_s=0.2,
                 on_stop=[lambda: log.info("step: on_stop"), woken.set],
                 declared=[Release()])
sys.exit(code)
"""


def start(robot_id: str, crash_after_s: float, log_path: Path) -> tuple[subprocess.Popen[bytes], Path]:
    out = log_path.open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-c", SERVICE, robot_id, str(crash_after_s)], stdout=out, stderr=out
    )
    return proc, log_path


def wait_for_text(path: Path, text: str, timeout: float = 20.0) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        log = path.read_text()
        if text in log:
            return log
        time.sleep(0.05)
    raise AssertionError(f"{text!r} not in the log:\n{path.read_text()}")


def test_serve_publishes_status_and_stops_in_order_on_sigterm(
    tmp_path: Path, robot_id: str, collect: Callable[[str], Collector]
) -> None:
    key = Keys(robot_id).status("demo")
    statuses = collect(key)
    proc, log_path = start(robot_id, 0.0, tmp_path / "demo.log")
    try:
        wait_for_text(log_path, "demo ready")
        assert len(statuses.wait_for(key, 3, timeout=10.0)) >= 3  # every period_s (0.2 s)
        assert statuses.models(key, ServiceStatus)[-1].service == "demo"
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(15) == 0
    finally:
        proc.kill()
    log = log_path.read_text()
    steps = ["demo stopping", "step: on_stop", "step: worker ended", "step: release", "demo stopped"]
    positions = [log.find(step) for step in steps]
    assert -1 not in positions and positions == sorted(positions), log
    assert "worker died" not in log and "Traceback" not in log


def test_serve_exits_1_when_its_worker_dies(tmp_path: Path, robot_id: str) -> None:
    proc, log_path = start(robot_id, 0.5, tmp_path / "demo.log")
    try:
        assert proc.wait(15) == 1  # without any signal: the dead worker ends the service
    finally:
        proc.kill()
    log = log_path.read_text()
    assert "worker demo crashed" in log and "demo worker failed" in log
    assert "demo worker died, exiting" in log and "demo stopped" not in log
    assert log.index("demo stopping") < log.index("step: release") < log.index("demo worker died, exiting")
