"""franky-sim as its own process, the arm service as another (connecting to the simulator's
address exactly as to a robot), and helpers to command it over Zenoh."""

from __future__ import annotations

import json
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import zenoh
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import ArmResult, ArmState, ErrorReply
from sofia_schemas.rosmsg import decode_flange_pose, decode_joint_state

from ..conftest import Proc

pytest.importorskip("franky_sim")
from sofia_arm.sim import SimProcess, start_sim


@dataclass
class Arm:
    """The arm service under test, its simulator and a session to talk to it."""

    keys: Keys
    session: zenoh.Session
    sim: SimProcess
    service: Proc
    poses: list[tuple[int, np.ndarray, np.ndarray]] = field(default_factory=list)  # (stamp, p, q_xyzw)
    joints: list[tuple[int, np.ndarray]] = field(default_factory=list)  # (stamp, q)
    states: list[ArmState] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def command(self, timeout: float = 200.0, **fields: object) -> zenoh.Reply:
        fields.setdefault("timeout_s", 180.0)  # franky-sim runs slower than real time on a busy machine
        payload = json.dumps(fields)
        deadline = time.monotonic() + 15.0
        while True:  # the first query may go out before discovery completes
            replies = list(self.session.get(self.keys.arm_command, payload=payload, encoding=ENCODING_JSON,
                                            timeout=timeout))  # fmt: skip
            if replies or time.monotonic() > deadline:
                assert replies, f"no reply to {fields}"
                return replies[0]  # the service's answer (a late query also ends with a timeout reply)
            time.sleep(0.2)

    def ok(self, **fields: object) -> ArmResult:
        reply = self.command(**fields)
        assert reply.ok is not None, reply.err.payload.to_bytes() if reply.err else None
        return ArmResult.model_validate_json(reply.ok.payload.to_bytes())

    def err(self, **fields: object) -> ErrorReply:
        reply = self.command(**fields)
        assert reply.err is not None, (
            f"expected an error reply, got {reply.ok.payload.to_bytes() if reply.ok else None}"
        )
        return ErrorReply.model_validate_json(reply.err.payload.to_bytes())

    def mean_pose(self, seconds: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
        """Published flange position and quaternion averaged over the last ``seconds`` (the
        simulator's wrist joint chatters by a fraction of a milliradian)."""
        time.sleep(seconds)
        with self.lock:
            t_end = self.poses[-1][0]
            recent = [(p, q) for t, p, q in self.poses if t >= t_end - seconds * 1e9]
        p = np.mean([r[0] for r in recent], axis=0)
        qs = np.array([r[1] * np.sign(r[1] @ recent[-1][1]) for r in recent])
        q = qs.mean(axis=0)
        return p, q / np.linalg.norm(q)

    def latest_state(self, timeout: float = 5.0) -> ArmState:
        n = len(self.states)
        deadline = time.monotonic() + timeout
        while len(self.states) == n and time.monotonic() < deadline:
            time.sleep(0.02)
        assert len(self.states) > n, "no arm state published"
        return self.states[-1]


@pytest.fixture(scope="module")
def arm(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Arm]:
    robot_id = "arm" + uuid.uuid4().hex[:8]
    sim = start_sim()
    log_dir: Path = tmp_path_factory.mktemp("arm")
    env = dict(os.environ, SOFIA_ROBOT=robot_id, PYTHONUNBUFFERED="1")
    # franky-sim simulates an FR3 (its MuJoCo model fr3.xml)
    service = Proc(
        ["arm", "serve", "--robot-ip", sim.host, "--model", "fr3", "--max-speed", "0.6"],
        log_dir / "arm.log",
        env,
    )
    try:
        service.wait_for_log("arm service ready", timeout=60)
        keys = Keys(robot_id)
        with zenoh.open(zenoh_config()) as session:
            a = Arm(keys, session, sim, service)

            def on_pose(sample: zenoh.Sample) -> None:
                pose = decode_flange_pose(sample.payload.to_bytes())
                with a.lock:
                    a.poses.append((pose.stamp_ns, np.array(pose.translation), np.array(pose.rotation_xyzw)))

            def on_joints(sample: zenoh.Sample) -> None:
                stamp, _, q, _, _ = decode_joint_state(sample.payload.to_bytes())
                with a.lock:
                    a.joints.append((stamp, q))

            def on_state(sample: zenoh.Sample) -> None:
                a.states.append(ArmState.model_validate_json(sample.payload.to_bytes()))

            subs = [session.declare_subscriber(keys.flange_pose, on_pose),
                    session.declare_subscriber(keys.arm_joint_states, on_joints),
                    session.declare_subscriber(keys.arm_state, on_state)]  # fmt: skip
            deadline = time.monotonic() + 30
            while not a.poses and time.monotonic() < deadline:
                time.sleep(0.05)
            assert a.poses, f"no flange pose published:\n{service.log()}"
            yield a
            for s in subs:
                s.undeclare()
    finally:
        service.stop()
        a_sim = getattr(locals().get("a"), "sim", sim)
        a_sim.stop()
        sim.stop()


def start_cell(sofia_proc: Callable[..., Proc], env: dict[str, str], camera: list[str], arm: list[str],
               detector: list[str]) -> list[Proc]:  # fmt: skip
    """The simulated cell on one world file (``env``): camera, arm, detector and emulated gripper
    services with these extra arguments, once camera, arm and detector are ready."""
    procs = [
        sofia_proc("camera", "serve", "--sim", "--sim-scene", "board", "--fps", "6", *camera, env=env),
        sofia_proc("arm", "serve", "--sim", "--max-speed", "1.0", *arm, env=env),
        sofia_proc("detector", "serve", *detector),
        sofia_proc("gripper", "serve", "--emulate", env=env),
    ]
    procs[1].wait_for_log("connected to the robot", 120)
    procs[0].wait_for_log("camera ready", 120)
    procs[2].wait_for_log("detector ready", 120)
    return procs
