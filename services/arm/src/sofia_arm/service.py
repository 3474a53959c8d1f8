"""The arm service: robot state onto the bus, commands from it.

- ``Keys(robot).flange_pose``: CDR TransformStamped panda_link0 -> panda_link8, the Panda FK of the
  measured joints, and ``Keys(robot).arm_joint_states``: CDR JointState, both at the state rate
  with the robot's time mapped onto the bus clock (same stamp for both);
- ``Keys(robot).arm_state``: JSON ArmState at ``state_publish_hz`` and when a command ends;
- queryable ``Keys(robot).arm_command``: JSON ArmCommand -> JSON ArmResult; bad or refused
  commands get an error reply;
- ``Keys(robot).status("arm")``: ServiceStatus every second, and queryable.

The query callback only queues. A dispatcher thread parses and checks each command, answers
``stop`` at once and hands the others to the command thread (preempting the running one).
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import zenoh
from sofia_runtime import serve
from sofia_runtime.service import StatusEndpoint, StopFlag, query_message, reply_error, reply_json, run_worker
from sofia_runtime.zenoh_config import ZenohOptions, zenoh_config
from sofia_schemas.errors import PayloadError
from sofia_schemas.keys import ENCODING_CDR_JOINT_STATE, ENCODING_CDR_TRANSFORM, ENCODING_JSON, Keys
from sofia_schemas.messages import ArmCommand, ArmState, FlangePose, GripperState, ServiceStatus, now_ns
from sofia_schemas.rosmsg import encode_flange_pose, encode_joint_state
from sofia_schemas.transforms import matrix_to_quat_xyzw, pose_gap

from .commands import Commands
from .config import ArmConfig
from .controller import Controller, Token
from .errors import ArmError
from .robot import RateMeter, RobotLink, Sample
from .safety import Safety
from .sim import SimProcess, start_sim
from .world import WorldKeeper

log = logging.getLogger(__name__)
JOINT_NAMES = [f"panda_joint{i}" for i in range(1, 8)]


@dataclass
class ServiceConfig:
    arm: ArmConfig
    robot: str
    zenoh: ZenohOptions
    robot_ip: str | None = None
    sim: bool = False
    sim_world: Path | None = None  # the simulated world's file (objects carried by the fingers)


def parse_command(query: zenoh.Query) -> ArmCommand:
    return query_message(query, ArmCommand, "arm command")


class StatePublisher:
    """Publishes each robot state as a flange pose and a joint state (called on the state thread)."""

    def __init__(self, session: zenoh.Session, keys: Keys) -> None:
        self.pose_pub = session.declare_publisher(keys.flange_pose, encoding=ENCODING_CDR_TRANSFORM)
        self.joints_pub = session.declare_publisher(keys.arm_joint_states, encoding=ENCODING_CDR_JOINT_STATE)
        self.published = 0
        self.rate = RateMeter()
        self.on_pose: Callable[[np.ndarray], None] | None = None  # each flange pose (4, 4), base frame

    def __call__(self, s: Sample) -> None:
        T = s.T_base_flange
        pose = FlangePose(stamp_ns=s.stamp_ns, translation=tuple(float(v) for v in T[:3, 3]),  # type: ignore[arg-type]
                          rotation_xyzw=tuple(float(v) for v in matrix_to_quat_xyzw(T[:3, :3])))  # type: ignore[arg-type]  # fmt: skip
        self.pose_pub.put(encode_flange_pose(pose))
        self.joints_pub.put(encode_joint_state(s.stamp_ns, JOINT_NAMES, s.q, s.dq, s.tau))
        self.published += 1
        self.rate.tick()
        if self.on_pose is not None:
            self.on_pose(T)


class GripperMonitor:
    """The newest gripper state; its error while fresh."""

    def __init__(self, max_age_s: float) -> None:
        self.max_age_s = max_age_s
        self.state: GripperState | None = None
        self.received = 0.0

    def on_sample(self, sample: zenoh.Sample) -> None:
        try:
            self.state = GripperState.model_validate_json(sample.payload.to_bytes())
            self.received = time.monotonic()
        except ValueError as e:
            log.warning("ignoring a malformed gripper state: %s", e)

    def error(self) -> str | None:
        s = self.state
        if s is None or time.monotonic() - self.received > self.max_age_s:
            return None
        if s.status == "error":
            return s.error or ", ".join(s.hardware_error) or "error"
        return None


class ArmService:
    def __init__(self, commands: Commands, publisher: StatePublisher | None) -> None:
        self.commands = commands
        self.controller = commands.controller
        self.publisher = publisher
        self.inbox: queue.Queue[zenoh.Query | None] = queue.Queue()
        self.work: queue.Queue[tuple[zenoh.Query, ArmCommand, Token] | None] = queue.Queue()
        self.errors = 0
        self.counters = {"commands": 0, "refused": 0, "failed": 0}
        self.changed = threading.Event()
        self.fk_check: tuple[float, float] | None = None  # (mm, deg): FK vs the robot's pose, at rest

    def check_fk(self) -> None:
        """At rest, compare the flange pose of the Panda FK with the robot's O_T_EE with the
        end-effector transform removed (they differ during motion in franky-sim, where O_T_EE lags)."""
        link = self.controller.link
        s = link.latest
        if (
            s is None
            or self.controller.current is not None
            or not link.is_still(self.controller.config.still_speed_rad_s, seconds=0.5)
        ):
            return
        dp, dr = pose_gap(s.O_T_EE @ np.linalg.inv(s.F_T_EE), s.T_base_flange)
        dr = float(np.degrees(dr))
        if self.fk_check is None or (dp > 1e-3 and self.fk_check[0] <= 1.0):
            level = logging.WARNING if dp > 1e-3 else logging.INFO
            log.log(
                level,
                "flange pose from the Panda FK vs the robot's O_T_EE F_T_EE^-1 at rest: %.4f mm, %.4f deg",
                dp * 1e3,
                dr,
            )
        self.fk_check = (dp * 1e3, dr)

    def dispatch(self) -> None:
        while (query := self.inbox.get()) is not None:
            try:
                cmd = parse_command(query)
                self.counters["commands"] += 1
                log.info("arm command %s received", cmd.command)
                if cmd.command == "stop":
                    reply_json(query, self.commands.stop(cmd))
                    self.changed.set()
                    continue
                self.commands.check(cmd)
            except (PayloadError, ArmError) as e:
                self.counters["refused"] += 1
                log.warning("arm command refused: %s", e)
                reply_error(query, e)
                continue
            except Exception as e:  # the dispatcher must survive, and the caller must get an answer
                self.counters["failed"] += 1
                log.exception("arm command check failed")
                reply_error(query, e)
                continue
            token = self.controller.begin(cmd.command, cmd.timeout_s)
            self.changed.set()
            self.work.put((query, cmd, token))
        self.work.put(None)

    def work_loop(self) -> None:
        while (item := self.work.get()) is not None:
            query, cmd, token = item
            try:
                result = self.commands.run(cmd, token)
            except ArmError as e:
                self.counters["refused"] += 1
                log.warning("arm %s refused: %s", cmd.command, e)
                reply_error(query, e)
            except Exception as e:
                self.counters["failed"] += 1
                log.exception("arm %s failed", cmd.command)
                reply_error(query, e)
            else:
                log.info("arm %s: %s (%s)", cmd.command, result.status, result.reason)
                reply_json(query, result)
            self.changed.set()

    def publish_states(self, state_pub: zenoh.Publisher, period_s: float, stop: threading.Event) -> None:
        """Publish the ArmState on ``state_pub`` every ``period_s`` s and as soon as a command
        changes it (:attr:`changed`), checking the FK at rest each time, until ``stop`` is set."""
        while not stop.is_set():
            self.changed.wait(period_s)
            self.changed.clear()
            self.check_fk()
            state_pub.put(self.state().to_json_bytes(), encoding=ENCODING_JSON)

    def state(self) -> ArmState:
        c, link = self.controller, self.controller.link
        s = link.latest
        current = c.current
        errors = ([link.error] if link.error else []) + (s.errors if s is not None else [])
        gripper = c.gripper_error()
        if gripper:
            errors.append(f"gripper: {gripper}")
        mode: Literal["idle", "moving", "error", "disconnected", "stopping"] = "idle"
        if link.robot is None:
            mode = "disconnected"
        elif errors or (s is not None and s.robot_mode in ("Reflex", "UserStopped")):
            mode = "error"
        elif current is not None or (s is not None and s.robot_mode == "Move"):
            mode = "moving"
        fields: dict[str, object] = {}
        if s is not None:
            T = s.T_base_flange
            fields = {"q": tuple(float(v) for v in s.q), "position": tuple(float(v) for v in T[:3, 3]),
                      "quaternion_xyzw": tuple(float(v) for v in matrix_to_quat_xyzw(T[:3, :3]))}  # fmt: skip
        return ArmState.model_validate({
            "stamp_ns": s.stamp_ns if s is not None else now_ns(), "connected": link.robot is not None,
            "mode": mode, "robot_mode": s.robot_mode if s is not None else "", "moving": mode == "moving",
            "errors": errors, "current_command": current.command if current is not None else None,
            "last_command": c.last_command, "last_result": c.last_result,
            "state_rate_hz": link.rate.hz(), "robot_rate_hz": link.robot_rate_hz(), "publish_rate_hz": self.publisher.rate.hz() if self.publisher else 0.0,
            **fields,
        })  # fmt: skip

    def status(self) -> ServiceStatus:
        link = self.controller.link
        st: Literal["ok", "degraded", "error"] = "ok"
        if link.robot is None:
            st = "error"
        elif link.error or (link.latest is not None and link.latest.errors):
            st = "degraded"
        counters = dict(
            link.counters, **self.counters, published=self.publisher.published if self.publisher else 0
        )
        return ServiceStatus(service="arm", stamp_ns=now_ns(), state=st, detail=link.error or "", counters=counters,
                             info={"robot_ip": link.host, "model": link.config.model,
                                   "fk_vs_robot_mm": self.fk_check[0] if self.fk_check else None,
                                   "fk_vs_robot_deg": self.fk_check[1] if self.fk_check else None})  # fmt: skip


def main(config: ServiceConfig) -> int:
    """Run the service until SIGINT/SIGTERM."""
    stop = StopFlag()
    keys = Keys(config.robot)
    with contextlib.ExitStack() as cleanup:  # the simulator goes whatever happens
        host = config.robot_ip
        if config.sim:
            sim: SimProcess = start_sim()
            cleanup.callback(sim.stop)
            host = sim.host
        if not host:
            raise ArmError("no robot: give --robot-ip IP or --sim")
        session = cleanup.enter_context(zenoh.open(zenoh_config(config.zenoh)))
        publisher = StatePublisher(session, keys)
        gripper = GripperMonitor(config.arm.gripper_state_max_age_s)
        session.declare_subscriber(keys.gripper_state, gripper.on_sample)
        if config.sim_world is not None:
            world = WorldKeeper(config.sim_world, Safety(config.arm).tool.fingertip_offset_m)
            publisher.on_pose = world.on_pose
            session.declare_subscriber(keys.gripper_state, world.on_gripper_sample)
            world.start()
            cleanup.callback(world.close)
            log.info("simulated world in %s", config.sim_world)
        link = RobotLink(host, config.arm, on_sample=publisher)
        controller = Controller(link, config.arm, gripper.error)
        service = ArmService(Commands(controller, session, keys), publisher)
        state_pub = session.declare_publisher(keys.arm_state, encoding=ENCODING_JSON)
        link.start()
        cleanup.callback(link.close)
        commands = session.declare_queryable(keys.arm_command, service.inbox.put)
        status = StatusEndpoint(session, keys.status("arm"), service.status)
        period_s = 1.0 / config.arm.state_publish_hz
        workers = [
            run_worker("arm-dispatch", service.dispatch),
            run_worker("arm-commands", service.work_loop),
            run_worker("arm-state", lambda: service.publish_states(state_pub, period_s, stop.event)),
        ]
        log.info(
            "arm service ready: robot %s, commands on %s, poses on %s",
            host,
            keys.arm_command,
            keys.flange_pose,
        )
        on_stop = [commands.undeclare, lambda: controller.cancel_current("stopped", "the arm service is stopping"),
                   controller.halt, lambda: service.inbox.put(None)]  # fmt: skip
        return serve(stop, status, workers, name="arm service", log=log, on_stop=on_stop, join_timeout_s=10.0)
