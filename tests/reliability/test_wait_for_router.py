"""With ``SOFIA_ZENOH_CONFIG`` set, a service still waits for its router (it used to exit within a
second when the router was down) and joins it once it is up."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.client import ask
from sofia_schemas import Keys
from sofia_schemas.messages import ServiceStatus

from .conftest import free_port


def test_a_service_with_a_config_file_waits_for_its_router(
    sofia_proc: Callable[..., object], tmp_path: Path, robot_id: str
) -> None:
    port = free_port()
    config = tmp_path / "client.json5"
    config.write_text(f'{{ mode: "client", connect: {{ endpoints: ["tcp/127.0.0.1:{port}"] }} }}\n')
    env = {"SOFIA_ZENOH_CONFIG": str(config)}
    service = sofia_proc("detector", "serve", env=env)
    service.wait_for_log("waiting until reachable")  # type: ignore[attr-defined]
    time.sleep(3.0)
    assert service.popen.poll() is None, f"exited while the router was down:\n{service.log()}"  # type: ignore[attr-defined]
    sofia_proc("router", "--listen", f"tcp/127.0.0.1:{port}").wait_for_log("router ready")  # type: ignore[attr-defined]
    service.wait_for_log("detector ready", timeout=60)  # type: ignore[attr-defined]
    with zenoh.open(zenoh_config(env=dict(os.environ, **env))) as session:
        status = ask(session, Keys(robot_id).status("detector"), ServiceStatus, timeout=30)
    assert status.service == "detector"
