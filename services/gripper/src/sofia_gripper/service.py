"""The gripper service: commands in, results and state out, over Zenoh.

- queryable ``Keys(robot).gripper_command``: JSON :class:`GripperCommand` -> JSON
  :class:`GripperResult`; malformed or impossible commands get an error reply;
- publisher ``Keys(robot).gripper_state``: JSON :class:`GripperState` every state cycle;
- ``Keys(robot).status("gripper")``: :class:`ServiceStatus` every second, and queryable.

The query callback only queues the query. A dispatcher thread parses it and answers ``stop`` and
``state`` at once (so ``stop`` can interrupt a running grasp); motion commands wait in a bounded
queue and run one at a time on the command thread (:mod:`~sofia_gripper.command_queue`). ``stop``
ends the running command and answers every queued one ``stopped``.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import zenoh
from sofia_runtime.service import (
    StatusEndpoint,
    StopFlag,
    query_message,
    reply_error,
    reply_json,
    run_worker,
    serve,
    stop_child,
)
from sofia_runtime.zenoh_config import ZenohOptions, zenoh_config
from sofia_schemas.errors import PayloadError
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import GripperCommand, GripperState, ServiceStatus, now_ns

from .command_queue import CommandQueue
from .commands import Gripper
from .config import GripperConfig, save_config
from .errors import GripperError

log = logging.getLogger(__name__)
IMMEDIATE = {"stop", "state"}
EMULATED_REPLY_MARGIN_MS = 200.0  # the emulator is a process on this host: a loaded host delays its replies


@dataclass
class ServiceConfig:
    gripper: GripperConfig
    robot: str
    zenoh: ZenohOptions
    emulate: bool = False
    object_width_mm: float | None = None


def parse_command(query: zenoh.Query) -> GripperCommand:
    return query_message(query, GripperCommand, "gripper command")


class GripperService:
    def __init__(self, gripper: Gripper) -> None:
        self.gripper = gripper
        self.inbox: queue.Queue[zenoh.Query | None] = queue.Queue()
        self.work = CommandQueue(gripper, self.run_command)
        self.errors = 0

    def run_command(self, query: zenoh.Query, cmd: GripperCommand) -> None:
        """Execute ``cmd`` and answer ``query`` (the reply finalises it); never raises. Motion
        commands come from :class:`CommandQueue`, which cleared the stop flag before."""
        try:
            result = self.gripper.execute(cmd, clear_abort=False)
        except GripperError as e:
            self.errors += 1
            log.warning("gripper %s refused: %s", cmd.action, e)
            reply_error(query, e)
            return
        except Exception as e:  # the command thread must survive, and the caller must get an answer
            self.errors += 1
            log.exception("gripper %s failed", cmd.action)
            reply_error(query, e)
            return
        reply_json(query, result)

    def dispatch(self) -> None:
        while (query := self.inbox.get()) is not None:
            try:
                cmd = parse_command(query)
            except PayloadError as e:
                self.errors += 1
                log.warning("%s", e)
                reply_error(query, e)
                continue
            if cmd.action == "stop":
                cancelled = self.work.stop()
                log.info("gripper stop: the running command ends, %d queued cancelled", cancelled)
                self.run_command(query, cmd)
            elif cmd.action in IMMEDIATE:
                self.run_command(query, cmd)
            else:
                try:
                    self.work.put(query, cmd)
                except GripperError as e:
                    self.errors += 1
                    log.warning("%s", e)
                    reply_error(query, e)
        self.work.close()

    def work_loop(self) -> None:
        self.work.work_loop()

    def status(self) -> ServiceStatus:
        g = self.gripper
        s = g.state
        state: Literal["ok", "degraded", "error"] = "ok" if s.connected and not s.error else "degraded"
        state = state if s.connected else "error"
        counters = dict(g.counters, command_errors=self.errors, **self.work.counters)
        return ServiceStatus(
            service="gripper", stamp_ns=now_ns(), state=state, detail=s.error or "", counters=counters,
            info={"port": g.config.port, "baud": g.config.baud, "id": g.config.dxl_id, "protocol": g.config.protocol},
        )  # fmt: skip


@dataclass
class EmulatorProcess:
    """``sofia gripper emulate`` running beside the service, as a real servo would: in its own
    process, so its timing does not depend on the service's threads."""

    popen: subprocess.Popen[str]
    path: str

    def stop(self) -> None:
        stop_child(self.popen)


def start_emulator(gconf: GripperConfig, object_width_mm: float | None, workdir: Path) -> EmulatorProcess:
    """Start an emulated MX-64 following ``gconf`` and return its tty path."""
    config_file = workdir / "gripper.yaml"
    save_config(gconf, config_file)
    sofia = Path(sys.executable).with_name("sofia")
    cmd = [str(sofia), "gripper", "emulate", "--protocol", f"{float(gconf.protocol):.1f}", "--baud", str(gconf.baud),
           "--id", str(gconf.dxl_id), "--link", str(workdir / "ttyDXL"), "--config", str(config_file), "--exit-with-stdin"]  # fmt: skip
    if object_width_mm is not None:
        cmd += ["--object-width", str(object_width_mm)]
    popen = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert popen.stdout is not None
    path = popen.stdout.readline().strip()
    if not path:
        popen.kill()
        raise GripperError(f"the emulator did not start (exit {popen.wait(5)}): {' '.join(cmd)}")
    log.info("emulated MX-64 on %s (pid %d)", path, popen.pid)
    return EmulatorProcess(popen, path)


def main(config: ServiceConfig) -> int:
    """Run the service until SIGINT/SIGTERM."""
    stop = StopFlag()
    keys = Keys(config.robot)
    with contextlib.ExitStack() as cleanup:  # the emulator and its directory go whatever happens
        gconf = config.gripper
        if config.emulate:
            tmp = cleanup.enter_context(tempfile.TemporaryDirectory(prefix="sofia-gripper-"))
            emulator = start_emulator(gconf, config.object_width_mm, Path(tmp))
            cleanup.callback(emulator.stop)
            margin = max(gconf.reply_margin_ms, EMULATED_REPLY_MARGIN_MS)
            gconf = gconf.model_copy(update={"port": emulator.path, "reply_margin_ms": margin})
        session = cleanup.enter_context(zenoh.open(zenoh_config(config.zenoh)))
        state_pub = session.declare_publisher(keys.gripper_state)

        def publish_state(state: GripperState) -> None:
            state_pub.put(state.to_json_bytes(), encoding=ENCODING_JSON)

        gripper = Gripper(gconf, on_state=publish_state)
        service = GripperService(gripper)
        commands = session.declare_queryable(keys.gripper_command, service.inbox.put)
        status = StatusEndpoint(session, keys.status("gripper"), service.status)
        gripper.start()
        workers = [
            run_worker("gripper-dispatch", service.dispatch),
            run_worker("gripper-commands", service.work_loop),
        ]
        log.info(
            "gripper service ready: commands on %s, state on %s", keys.gripper_command, keys.gripper_state
        )
        # the dispatcher passes the end (None) on to the command thread; a motion under way ends now
        on_stop = [commands.undeclare, lambda: service.inbox.put(None), gripper.abort.set]
        code = serve(
            stop, status, workers, name="gripper service", log=log, on_stop=on_stop, join_timeout_s=10.0
        )
        gripper.close(torque_off=False)  # keep holding; the bus watchdog stops motion
    return code
