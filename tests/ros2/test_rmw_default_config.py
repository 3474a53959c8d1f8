"""Fresh sessions opened from rmw_zenoh's own default session config (Jazzy: peer mode, the router
on tcp/localhost:7447 for discovery, gossip, peers dialled by the greater Zenoh id, the router's
endpoint overridden) discover SofIA's detections publisher and receive its detections from `sofia up
--ros2`, with the router on a loopback port and on all interfaces."""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import time
import uuid
from pathlib import Path

import pytest
import zenoh
from sofia_runtime.client import ask
from sofia_runtime.ros2.rmw import data_key
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas.frames import BASE_FRAME
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import DetectedObject, Detection, ServiceStatus
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.ros2.typesupport import decode

from ..conftest import SOFIA
from .conftest import free_port, wait_port

RMW_SESSION_CONFIG = Path(__file__).with_name("data") / "DEFAULT_RMW_ZENOH_SESSION_CONFIG.jazzy.json5"
FRESH_SESSIONS = 10
SESSION_TIMEOUT_S = 20.0  # each took under 1.1 s here


def rmw_session_config(router_port: int) -> zenoh.Config:
    """rmw_zenoh's default session config with the router's endpoint overridden (what
    ``ZENOH_CONFIG_OVERRIDE='connect/endpoints=["tcp/localhost:PORT"]'`` does)."""
    conf = zenoh.Config.from_file(str(RMW_SESSION_CONFIG))
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/localhost:{router_port}"]))
    return conf


def _detection(n: int) -> Detection:
    obj = DetectedObject(center=(0.5, 0.0, 0.03), centroid=(0.5, 0.0, 0.04), extents=(0.04, 0.04, 0.06), yaw=0.0,
                         field=(1, 1), allowed=True, n_points=100, confidence=0.9)  # fmt: skip
    return Detection(stamp_ns=1_000 + n, frame_id=BASE_FRAME, status="ok", objects=[obj])


@pytest.mark.parametrize("port_kind", ["loopback", "all-interfaces"])
def test_fresh_rmw_default_sessions_discover_and_receive(tmp_path: Path, port_kind: str) -> None:
    robot = f"r{uuid.uuid4().hex[:8]}"
    port = free_port()
    domain = str(100 + int(uuid.uuid4().int % 100))  # away from other runs on this host
    env = dict(os.environ, ROS_DOMAIN_ID=domain)
    router = ["--router-listen", f"tcp/127.0.0.1:{port}"]
    if port_kind == "all-interfaces":  # a router reachable from other machines too
        router = ["--router-listen", f"tcp/0.0.0.0:{port}"]
    up = subprocess.Popen([SOFIA, "up", "--ros2", "--services", "detector", "--robot", robot, *router,
                           "--state-dir", str(tmp_path / "state"), "--log-dir", str(tmp_path / "log")],
                          env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip
    topic = f"/sofia/{robot}/detections"
    key = data_key(int(domain), topic, cv.DETECTIONS)
    # the publisher's liveliness token, found as rmw_zenoh finds the graph (every token of the domain)
    token = f"/MP/%/%/sofia_detector/{topic.replace('/', '%')}/"
    results: list[str] = []
    try:
        wait_port(port, timeout=60)
        with zenoh.open(zenoh_config()) as sofia:  # SofIA's side: detections as the detector publishes them
            ask(sofia, Keys(robot).status("ros2"), ServiceStatus, timeout=60)  # the bridge is up
            for i in range(FRESH_SESSIONS):
                got: queue.Queue[bytes] = queue.Queue()
                t0 = time.monotonic()
                with zenoh.open(rmw_session_config(port)) as ros:
                    sub = ros.declare_subscriber(key, lambda s, got=got: got.put(s.payload.to_bytes()))
                    found = False
                    received = None
                    while time.monotonic() - t0 < SESSION_TIMEOUT_S and not (found and received is not None):
                        tokens = ros.liveliness().get(f"@ros2_lv/{domain}/**", timeout=1.0)
                        found = found or any(token in str(r.ok.key_expr) for r in tokens if r.ok)
                        sofia.put(
                            Keys(robot).detections, _detection(i).to_json_bytes(), encoding=ENCODING_JSON
                        )
                        try:
                            received = got.get(timeout=0.5) if received is None else received
                        except queue.Empty:
                            continue
                    sub.undeclare()
                ok = found and received is not None and len(decode(received, cv.DETECTIONS).detections) == 1
                results.append(f"session {i}: {'ok' if ok else 'FAILED'} (discovered {found}, "
                               f"received {received is not None}) in {time.monotonic() - t0:.1f} s")  # fmt: skip
                if not ok:  # one failure is enough (each waits SESSION_TIMEOUT_S)
                    break
    finally:
        up.send_signal(signal.SIGINT)
        try:
            up.wait(60)
        except subprocess.TimeoutExpired:
            os.killpg(up.pid, signal.SIGKILL)
    logs = {p.name: p.read_text(errors="replace")[-600:] for p in (tmp_path / "log").glob("*.log")}
    assert all(r.split(":")[1].startswith(" ok") for r in results) and len(results) == FRESH_SESSIONS, (
        results,
        logs,
    )
