"""franky-sim (a MuJoCo Franka speaking the libfranka network protocol) as a separate process.

``franky-sim --simulator mujoco`` binds the first free loopback address
(127.0.0.1, else 127.0.0.2, ...) on libfranka's ports and prints it; :func:`start_sim` waits for
that line. ``--hostname`` forces an address (a restarted simulator takes its predecessor's). On
Linux the simulator gets SIGTERM when the process that started it dies, even by SIGKILL.
"""

from __future__ import annotations

import ctypes
import logging
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from sofia_runtime.service import stop_child

from .errors import SimError

log = logging.getLogger(__name__)
READY_RE = re.compile(r"using '([0-9.]+)' as the robot IP address")
START_TIMEOUT_S = 60.0


def _exit_with_parent() -> None:
    """In the child before exec: SIGTERM when the parent dies (prctl PR_SET_PDEATHSIG)."""
    ctypes.CDLL(None).prctl(1, signal.SIGTERM)


@dataclass
class SimProcess:
    """A running franky-sim: its address and process."""

    popen: subprocess.Popen[str]
    host: str

    def stop(self) -> None:
        """Terminate (SIGTERM, then SIGKILL after 5 s)."""
        stop_child(self.popen)

    def kill(self) -> None:
        """Kill at once, as a robot losing power or its network."""
        self.popen.kill()
        self.popen.wait(5)


def start_sim(hostname: str | None = None, timeout_s: float = START_TIMEOUT_S) -> SimProcess:
    """Start franky-sim headless (optionally on ``hostname``) and return once it accepts clients."""
    try:
        import franky_sim  # noqa: F401
    except ImportError as e:
        raise SimError(f"franky-sim is not installed (pip install 'sofia-arm[sim]'): {e}") from None
    script = Path(sys.executable).with_name("franky-sim")
    launch = (
        [str(script)]
        if script.exists()
        else [sys.executable, "-c", "from franky_sim.run_server import main; main()"]
    )
    cmd = [*launch, "--simulator", "mujoco"]
    if hostname:
        cmd += ["--hostname", hostname]
    env = dict(os.environ, PYTHONUNBUFFERED="1", MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    popen = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True, env=env, preexec_fn=_exit_with_parent if sys.platform == "linux" else None)  # fmt: skip
    assert popen.stdout is not None
    lines: list[str] = []
    found: list[str] = []

    def read() -> None:  # keeps draining the pipe so the simulator never blocks on a full pipe
        assert popen.stdout is not None
        for line in popen.stdout:
            if not found and (m := READY_RE.search(line)):
                found.append(m.group(1))
            if len(lines) < 200:
                lines.append(line.rstrip())
            log.debug("franky-sim: %s", line.rstrip())

    threading.Thread(target=read, name="franky-sim-output", daemon=True).start()
    deadline = time.monotonic() + timeout_s
    while not found:
        if popen.poll() is not None or time.monotonic() > deadline:
            popen.kill()
            popen.wait(5)
            raise SimError(
                f"franky-sim did not start (exit {popen.returncode}): {' '.join(cmd)}\n"
                + "\n".join(lines[-20:])
            )
        time.sleep(0.05)
    log.info("franky-sim on %s (pid %d)", found[0], popen.pid)
    return SimProcess(popen, found[0])
