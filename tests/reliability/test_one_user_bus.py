"""One user's bus: while the detector runs with SofIA's default bus, a process of another user
(``nobody``) opens a Zenoh peer the way the issue's campaign did (multicast scouting on ``lo``, a
Unix socket of its own, and dialling the paths of SofIA's sockets it was told) and reaches
nothing: no reply, no sample, and no SofIA process queries it. The same probe run as this user
reaches the detector: the test can tell the difference."""

from __future__ import annotations

import json
import os
import subprocess
import threading
import uuid
from pathlib import Path

import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.zenoh_config import socket_dir
from sofia_schemas import Keys

from .conftest import Service

NOBODY = 65534
SYSTEM_PYTHON = "/usr/bin/python3"  # another user cannot run this venv's interpreter (under /root)
PROBE = r"""
import json, os, sys, tempfile, threading, time
import zenoh
robot, sockets = sys.argv[1], json.loads(sys.argv[2])
own = tempfile.mkdtemp(prefix="probe-")
conf = zenoh.Config()
conf.insert_json5("scouting/multicast/enabled", "true")
conf.insert_json5("scouting/multicast/interface", '"lo"')
conf.insert_json5("listen/endpoints", json.dumps([f"unixsock-stream/{own}/z.sock"]))
conf.insert_json5("connect/endpoints", json.dumps(sockets))
conf.insert_json5("connect/timeout_ms", '{"router": 0, "peer": 0, "client": 0}')
conf.insert_json5("connect/exit_on_failure", '{"router": false, "peer": false, "client": false}')
seen = {"replies": 0, "samples": 0, "queried": 0}
lock = threading.Lock()
def count(name):
    def cb(_):
        with lock:
            seen[name] += 1
    return cb
with zenoh.open(conf) as s:
    s.declare_subscriber(f"sofia/{robot}/**", count("samples"))
    def forged(q):
        count("queried")(q)
        q.reply(q.key_expr, b'{"forged": true}')
    s.declare_queryable(f"sofia/{robot}/calibrator/result", forged)
    deadline = time.monotonic() + float(sys.argv[3])
    while time.monotonic() < deadline:
        for key in (f"sofia/{robot}/detector/status", f"sofia/{robot}/detector/detect"):
            for r in s.get(key, timeout=0.5):
                if r.ok is not None:
                    count("replies")(r)
print(json.dumps(seen), flush=True)
"""


def probe(robot: str, user: int | None, seconds: float, env: dict[str, str]) -> dict[str, int]:
    """Run the probe peer as ``user`` (None: this user) against the sockets of SofIA's bus."""
    sockets = [f"unixsock-stream/{p}" for p in socket_dir(env).glob("*.sock")]
    assert sockets, f"no socket of the bus in {socket_dir(env)}"

    def drop() -> None:
        os.setgroups([])
        os.setgid(NOBODY)
        os.setuid(NOBODY)

    site = str(Path(zenoh.__file__).parents[1])  # the zenoh package only, readable by everyone
    probe_env = {"HOME": "/tmp", "TMPDIR": "/tmp", "PYTHONPATH": site, "PATH": "/usr/bin:/bin"}
    out = subprocess.run([SYSTEM_PYTHON, "-c", PROBE, robot, json.dumps(sockets), str(seconds)],
                         capture_output=True, text=True, timeout=60, env=probe_env,
                         preexec_fn=drop if user is not None else None)  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_another_user_reaches_nothing(tmp_path: Path) -> None:
    """The bus of this test has its own socket directory (SOFIA_ZENOH_SOCKET_DIR): other processes
    of this user on the machine (of other versions, with scouting) are not part of it."""
    robot = "tuser" + uuid.uuid4().hex[:6]
    keys = Keys(robot)
    env = dict(
        os.environ, SOFIA_ROBOT=robot, PYTHONUNBUFFERED="1", SOFIA_ZENOH_SOCKET_DIR=str(tmp_path / "bus")
    )
    directory = socket_dir(env)
    assert directory.stat().st_mode & 0o777 == 0o700 and directory.stat().st_uid == os.getuid()
    detector = Service(["detector", "serve"], env, tmp_path / "detector.log")
    try:
        detector.wait_for_log("detector ready")
        with zenoh.open(zenoh_config(env=env)) as session:  # a SofIA session of this user
            pub = session.declare_publisher(keys.detections)
            done = threading.Event()

            def traffic() -> None:  # publishes, and asks the calibrator's result (the probe forges one)
                while not done.is_set():
                    pub.put(b"{}")
                    list(session.get(keys.calibration_result, timeout=0.3))

            worker = threading.Thread(target=traffic, daemon=True)
            worker.start()
            try:
                as_nobody = probe(robot, NOBODY, 5.0, env)
                as_me = probe(robot, None, 5.0, env)  # the control
            finally:
                done.set()
                worker.join(5)
    finally:
        detector.stop()
    print(f"as nobody: {as_nobody}; as this user: {as_me}")
    assert as_nobody == {"replies": 0, "samples": 0, "queried": 0}
    assert as_me["replies"] > 0 and as_me["samples"] > 0 and as_me["queried"] > 0
