"""``sofia up``'s launcher starts the router first and the services once it listens.

A session dials the local sockets present when it opens (``sofia_runtime.zenoh_config``). Started
together, a service could list the socket directory before the router's socket existed and the
router list it before the service's did: neither dialled the other, and a ROS 2 node connected to
the router alone saw no SofIA topic (``tests/ros2/test_rmw_default_config.py``, about 1 run in 40).
"""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path

import pytest
import zenoh
from sofia_runtime.client import ask
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ServiceStatus
from sofia_system.launcher import Launcher, ServiceSpec

from ..ros2.conftest import free_port


def test_the_router_listens_before_the_services_start(tmp_path: Path) -> None:
    robot = f"lo{uuid.uuid4().hex[:8]}"
    sockets = tmp_path / "sockets"  # a bus of this test's own
    env = dict(os.environ, SOFIA_ZENOH_SOCKET_DIR=str(sockets))
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    specs = [ServiceSpec("detector", ["detector", "serve"], "detector"),  # listed first on purpose
             ServiceSpec("router", ["router", "--listen", endpoint])]  # fmt: skip
    launcher = Launcher(specs, tmp_path / "log", robot, env=env, restart=False)
    launcher.start()
    try:
        router, detector = (launcher.procs[name].popen for name in ("router", "detector"))
        assert router is not None and detector is not None
        assert list(sockets.glob(f"{router.pid}-*.sock")), "start() returned before the router listened"
        # the detector reached the router: a client of the router's TCP port alone gets its status
        conf = zenoh.Config()
        conf.insert_json5("mode", '"client"')
        conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
        with zenoh.open(conf) as session:
            status = ask(session, Keys(robot).status("detector"), ServiceStatus, timeout=60)
        assert status.service == "detector"
    finally:
        launcher.stop()


def test_an_error_while_starting_stops_what_was_started(tmp_path: Path) -> None:
    """A config file that does not exist fails the wait for the router's socket: the router already
    started (in a session of its own, out of reach of Ctrl-C) is stopped, not left behind."""
    env = dict(os.environ, SOFIA_ZENOH_CONFIG=str(tmp_path / "missing.json5"),
               SOFIA_ZENOH_SOCKET_DIR=str(tmp_path / "sockets"))  # fmt: skip
    launcher = Launcher([ServiceSpec("router", ["router"])], tmp_path / "log", "lostop", env=env)
    with pytest.raises(FileNotFoundError, match=r"missing\.json5"):
        launcher.start()
    router = launcher.procs["router"]
    assert router.popen is None and router.exits == [], "the router was not stopped"
