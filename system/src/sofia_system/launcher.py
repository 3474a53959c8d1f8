"""``sofia up``: the router and every service as separate local processes, without Docker.

Each process writes its own log (``<log-dir>/<name>.log``); a process that dies is restarted
with a growing back-off; health comes from each service's status queryable; Ctrl-C (or SIGTERM)
stops everything cleanly (SIGTERM, then SIGKILL after a grace period).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import zenoh
from sofia_runtime.cli import EXIT_USAGE
from sofia_runtime.client import QueryError, ask
from sofia_runtime.output import add_json_option, emit
from sofia_runtime.ros2.cli import enabled as ros2_enabled
from sofia_runtime.service import StopFlag
from sofia_runtime.zenoh_config import (
    DEFAULT_ROUTER_LISTEN,
    ROS2_ROUTER_LISTEN,
    ZenohOptions,
    add_zenoh_args,
    wait_for_socket,
    zenoh_config,
)
from sofia_schemas.board import BOARD_HELP, default_board_path
from sofia_schemas.keys import Keys, default_robot
from sofia_schemas.messages import ServiceStatus

log = logging.getLogger("sofia.up")
GRACE_S = 8.0
MAX_BACKOFF_S = 10.0
START_WAIT_S = 30.0  # each process's wait for the one before it to listen


def sofia_executable() -> list[str]:
    """How to run the ``sofia`` command of this installation."""
    exe = Path(sys.executable).with_name("sofia")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("sofia")
    return [found] if found else [sys.executable, "-m", "sofia_runtime.cli"]


@dataclass
class ServiceSpec:
    """A process to run: ``sofia ARGS...``; ``status`` is the service name of its status key."""

    name: str
    args: list[str]
    status: str | None = None


@dataclass
class Managed:
    spec: ServiceSpec
    popen: subprocess.Popen[bytes] | None = None
    log_file: IO[bytes] | None = None
    restarts: int = 0
    next_start: float = 0.0
    backoff: float = 1.0
    state: str = "starting"
    exits: list[int] = field(default_factory=list)


class Launcher:
    """Starts, watches, restarts and stops SofIA processes."""

    def __init__(self, specs: list[ServiceSpec], log_dir: Path, robot: str, env: dict[str, str] | None = None,
                 restart: bool = True) -> None:  # fmt: skip
        self.procs = {s.name: Managed(s) for s in specs}
        self.log_dir = Path(log_dir)
        self.robot = robot
        self.env = dict(os.environ if env is None else env, SOFIA_ROBOT=robot, PYTHONUNBUFFERED="1")
        self.restart = restart
        self.log_dir.mkdir(parents=True, exist_ok=True)

    def _start(self, m: Managed) -> None:
        path = self.log_dir / f"{m.spec.name}.log"
        m.log_file = open(path, "ab")
        cmd = [*sofia_executable(), *m.spec.args]
        m.popen = subprocess.Popen(cmd, stdout=m.log_file, stderr=subprocess.STDOUT, env=self.env,
                                   start_new_session=True)  # fmt: skip
        m.state = "starting"
        log.info("started %-10s pid %d: %s (log %s)", m.spec.name, m.popen.pid, " ".join(m.spec.args), path)

    def start(self) -> None:
        """The router first, then each process once the one before listens (a session dials only the
        sockets there as it opens); an error or Ctrl-C meanwhile stops what was started."""
        try:
            for m in sorted(self.procs.values(), key=lambda m: m.spec.name != "router"):
                self._start(m)
                if m.popen and not wait_for_socket(m.popen, START_WAIT_S, self.env):
                    log.warning("%s: no local socket after %.0f s", m.spec.name, START_WAIT_S)
        except BaseException:
            self.stop()
            raise

    def poll(self) -> None:
        """Restart processes that exited (with back-off)."""
        now = time.monotonic()
        for m in self.procs.values():
            if m.popen is None or m.popen.poll() is None:
                if m.popen is None and now >= m.next_start:
                    self._start(m)
                continue
            m.exits.append(code := m.popen.returncode)
            if m.log_file:
                m.log_file.close()
            m.popen, m.state = None, "exited"
            log.warning(
                "%s exited with code %d (see %s)", m.spec.name, code, self.log_dir / f"{m.spec.name}.log"
            )
            if code == EXIT_USAGE:  # an input error (a busy port, a bad option): a restart repeats it
                m.state, m.next_start = "failed", math.inf
                log.error("%s failed: %s (not restarted)", m.spec.name, self.last_line(m.spec.name))
            elif self.restart:
                m.restarts += 1
                m.next_start = now + m.backoff
                m.backoff = min(MAX_BACKOFF_S, m.backoff * 2)
                log.info("restarting %s in %.0f s (restart %d)", m.spec.name, m.next_start - now, m.restarts)

    def last_line(self, name: str) -> str:
        """The last non-empty line of ``name``'s log (a failed command's one-line error)."""
        try:
            lines = (self.log_dir / f"{name}.log").read_text(errors="replace").splitlines()
        except OSError:
            return "no log"
        return next((line for line in reversed(lines) if line.strip()), "empty log")

    def failed(self) -> list[str]:
        """Processes that exited with an input error and are not restarted."""
        return [name for name, m in self.procs.items() if m.state == "failed"]

    def check_health(self, session: zenoh.Session, timeout: float = 1.0) -> dict[str, str]:
        keys = Keys(self.robot)
        for m in self.procs.values():
            if m.popen is None:
                continue
            if m.spec.status is None:
                m.state = "running"
                continue
            try:
                m.state = ask(session, keys.status(m.spec.status), ServiceStatus, timeout=timeout).state
            except (QueryError, ValueError) as e:  # silence, or a reply that is not a status
                m.state = "no status" if isinstance(e, QueryError) else "bad status"
            m.backoff = 1.0 if m.state == "ok" else m.backoff
        return {name: m.state for name, m in self.procs.items()}

    def rows(self) -> list[dict[str, Any]]:
        """One dict per process: service, pid (None when not running), state, restarts."""
        return [{"service": name, "pid": m.popen.pid if m.popen else None, "state": m.state,
                 "restarts": m.restarts} for name, m in self.procs.items()]  # fmt: skip

    def table(self) -> str:
        return health_table(self.rows())

    def stop(self) -> None:
        for m in self.procs.values():
            if m.popen is not None and m.popen.poll() is None:
                m.popen.terminate()
        deadline = time.monotonic() + GRACE_S
        for m in self.procs.values():
            if m.popen is None:
                continue
            try:
                m.popen.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                log.warning("%s did not stop in %.0f s, killing it", m.spec.name, GRACE_S)
                m.popen.kill()
                m.popen.wait(5)
            if m.log_file:
                m.log_file.close()
            log.info("stopped %s (exit %s)", m.spec.name, m.popen.returncode)
            m.popen = None


# states in which a service counts as up for the demo's and the cell's gates: the detector is
# degraded by design until the first calibration maps its camera-frame clouds
READY_STATES = {"detector": ("ok", "degraded")}


def all_ready(states: dict[str, str]) -> bool:
    """Whether every service of ``states`` (:meth:`Launcher.check_health`) is up: ok, running (no
    status), or a state :data:`READY_STATES` allows for it."""
    return all(state in (*READY_STATES.get(name, ("ok",)), "running") for name, state in states.items())


def health_table(rows: list[dict[str, Any]]) -> str:
    """The health table ``sofia up`` prints: service, pid, state, restarts."""
    lines = [f"{'service':<12}{'pid':>8}  {'state':<12}{'restarts':>8}"]
    lines += [f"{r['service']:<12}{r['pid'] or '-':>8}  {r['state']:<12}{r['restarts']:>8}" for r in rows]
    return "\n".join(lines)


def board_args(board: Path | None) -> list[str]:
    """``--board FILE`` of the detector: the given board, else the configured default
    (:func:`~sofia_schemas.board.default_board_path`), else nothing (the package's board)."""
    chosen = board or default_board_path()
    return ["--board", str(chosen)] if chosen else []


def default_specs(args: argparse.Namespace) -> list[ServiceSpec]:
    """The router, detector, calibrator and gripper (emulated unless a serial port is given)."""
    ros2 = getattr(args, "ros2", False) or ros2_enabled()
    listen = ["--listen", args.router_listen]
    # where rmw_zenoh nodes look (any local user can reach it); a TCP --router-listen is theirs instead
    if ros2 and not args.router_listen.startswith("tcp/"):
        listen += ["--listen", ROS2_ROUTER_LISTEN]
    specs = [ServiceSpec("router", ["router", *listen])]
    if "detector" in args.services:
        specs.append(ServiceSpec("detector", ["detector", "serve", *board_args(args.board)], "detector"))
    if "calibrator" in args.services:
        specs.append(
            ServiceSpec(
                "calibrator",
                ["calibrator", "serve", "--state-dir", str(args.state_dir / "calibrator")],
                "calibrator",
            )
        )
    if "gripper" in args.services:
        port = ["--port", args.gripper_port] if args.gripper_port else ["--emulate"]
        specs.append(ServiceSpec("gripper", ["gripper", "serve", *port], "gripper"))
    if "camera" in args.services:  # the D435 (opt-in: --services ...,camera), or its simulation
        sim = ["--sim"] if getattr(args, "camera_sim", False) else []
        specs.append(ServiceSpec("camera", ["camera", "serve", *sim], "camera"))
    if "arm" in args.services:  # the Franka (opt-in: --services ...,arm), or franky-sim without --robot-ip
        robot = ["--robot-ip", args.robot_ip] if getattr(args, "robot_ip", None) else ["--sim"]
        specs.append(ServiceSpec("arm", ["arm", "serve", *robot], "arm"))
    if ros2:
        specs.append(ServiceSpec("ros2", ["ros2", "serve"], "ros2"))  # SofIA on the ROS 2 graph (rmw_zenoh)
    return specs


def add_up_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--services", default="detector,calibrator,gripper", type=lambda s: s.split(","),
                   help="comma-separated services to run (default: detector,calibrator,gripper; "
                   "add camera for the D435, arm for the Franka)")  # fmt: skip
    p.add_argument("--board", type=Path, default=None, help=BOARD_HELP)
    p.add_argument("--state-dir", type=Path, default=Path("var"),
                   help="folder of the services' state, e.g. calibration samples in DIR/calibrator (default var)")  # fmt: skip
    p.add_argument("--log-dir", type=Path, default=Path("var/log"),
                   help="folder of the per-service logs, <service>.log (default var/log)")  # fmt: skip
    p.add_argument("--gripper-port", default=None, help="serial port of the real gripper (default: emulated)")
    p.add_argument("--camera-sim", action="store_true", help="camera: the simulated D435")
    p.add_argument("--robot-ip", default=None, help="arm: the Franka's FCI address (default: franky-sim)")
    p.add_argument("--router-listen", default=DEFAULT_ROUTER_LISTEN[0], metavar="ENDPOINT",
                   help=f"where the Zenoh router listens (default {DEFAULT_ROUTER_LISTEN[0]}: a socket only this "
                   f"user reaches; with --ros2 also {ROS2_ROUTER_LISTEN} unless ENDPOINT is TCP)")  # fmt: skip
    p.add_argument("--robot", default=None, help="robot id of every key (default $SOFIA_ROBOT or panda)")
    p.add_argument("--ros2", action="store_true",
                   help="also offer SofIA to ROS 2 nodes using rmw_zenoh (sofia ros2 serve); the router then "
                   f"also listens on {ROS2_ROUTER_LISTEN} (or only on a TCP --router-listen), open to every local "
                   "user; or $SOFIA_ROS2=1")  # fmt: skip


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "up", help="run the router and all services as local processes",
        description="Start a Zenoh router and the services as separate processes, print a health table "
        "when it changes, restart a crashed service with a growing back-off, write one log per service "
        "and stop everything cleanly on Ctrl-C.",
    )  # fmt: skip
    add_up_args(p)
    add_zenoh_args(p)
    add_json_option(p, "one object per change of the health table and line", "the health table")
    p.set_defaults(func=up)


def up(args: argparse.Namespace) -> int:
    stop = StopFlag()
    launcher = Launcher(default_specs(args), args.log_dir, args.robot or default_robot())
    launcher.start()
    shown: list[dict[str, Any]] = []
    try:
        with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
            while not stop.wait(1.0):
                launcher.poll()
                if "router" in launcher.failed():
                    print(f"sofia up: error: the router did not start: {launcher.last_line('router')}",
                          file=sys.stderr)  # fmt: skip
                    return EXIT_USAGE
                launcher.check_health(session)
                rows = launcher.rows()
                if rows != shown:
                    emit(args, {"services": rows}, health_table(rows))
                    shown = rows
    finally:
        launcher.stop()
    return 0
