"""The arm service against franky-sim (separate processes, the libfranka network protocol)."""

from __future__ import annotations

import json
import os
import subprocess
import threading
import time

import numpy as np
import pytest
from sofia_runtime.client import ask
from sofia_schemas.kinematics import panda_fk
from sofia_schemas.messages import ArmResult, GripperState, ServiceStatus
from sofia_schemas.transforms import make_transform, matrix_to_quat_xyzw

from ..conftest import SOFIA
from .conftest import Arm

HOME = np.array([0.0, 0.0, 0.0, -1.5708, 0.0, 1.5708, 0.7854])
Q_A = np.array([0.3, -0.3, 0.2, -2.0, 0.1, 1.8, 0.3])
Q_FAR = np.array([-0.6, 0.3, -0.2, -1.6, -0.1, 2.0, 1.2])


def angle_deg(q1: np.ndarray, q2: np.ndarray) -> float:
    return float(np.degrees(2 * np.arccos(min(1.0, abs(float(q1 @ q2))))))


def assert_at(arm: Arm, T_goal: np.ndarray, mm: float = 1.0, deg: float = 0.1) -> None:
    p, q = arm.mean_pose()
    err_mm = np.linalg.norm(p - T_goal[:3, 3]) * 1e3
    err_deg = angle_deg(q, matrix_to_quat_xyzw(T_goal[:3, :3]))
    assert err_mm <= mm and err_deg <= deg, f"{err_mm:.3f} mm, {err_deg:.4f} deg from the target"


def in_thread(arm: Arm, **fields: object) -> tuple[threading.Thread, list[ArmResult]]:
    out: list[ArmResult] = []
    t = threading.Thread(target=lambda: out.append(arm.ok(**fields)))
    t.start()
    return t, out


def test_flange_pose_is_fk_of_joint_states(arm: Arm) -> None:
    time.sleep(1.0)
    with arm.lock:
        poses = {t: (p, q) for t, p, q in arm.poses[-150:]}
        joints = arm.joints[-150:]
    pairs = [(poses[t], q) for t, q in joints if t in poses]
    assert len(pairs) >= 100, f"only {len(pairs)} joint states have a flange pose of the same stamp"
    T = panda_fk(np.array([q for _, q in pairs]))
    p_pub = np.array([p for (p, _), _ in pairs])
    q_pub = np.array([q for (_, q), _ in pairs])
    assert np.abs(np.linalg.norm(p_pub - T[:, :3, 3], axis=1)).max() * 1e3 < 0.1
    dots = np.abs(np.einsum("ni,ni->n", q_pub, matrix_to_quat_xyzw(T[:, :3, :3])))
    assert np.degrees(2 * np.arccos(np.clip(dots, -1, 1))).max() < 0.01
    stamps = np.array(sorted(poses))
    assert np.all(np.diff(stamps) > 0) and abs(stamps[-1] - time.time_ns()) < 2e9  # bus clock
    deadline = time.monotonic() + 60  # at rest for half a second of the robot's clock
    while (status := ask(arm.session, arm.keys.status("arm"), ServiceStatus)).info["fk_vs_robot_mm"] is None:
        assert time.monotonic() < deadline, status
        time.sleep(0.5)
    assert status.state == "ok"
    assert float(status.info["fk_vs_robot_mm"]) < 0.1 and float(status.info["fk_vs_robot_deg"]) < 0.01  # type: ignore[arg-type]


def test_move_joints_and_pose_reach_targets(arm: Arm) -> None:
    r = arm.ok(command="move_joints", q=Q_A.tolist(), speed=0.6)
    assert r.ok and r.status == "done", r
    assert np.abs(np.array(r.q) - Q_A).max() < 0.01
    assert_at(arm, panda_fk(Q_A))

    T_goal = make_transform(np.array([0.45, -0.1, 0.35]), np.array([1.0, 0.0, 0.0, 0.0]))
    r = arm.ok(command="move_pose", position=[0.45, -0.1, 0.35], quaternion_xyzw=[1, 0, 0, 0], speed=0.6)
    assert r.ok, r
    assert_at(arm, T_goal)
    state = arm.latest_state()
    assert state.mode == "idle" and state.last_command == "move_pose" and state.last_result is not None
    # joint 6 within the FR3's limits (to 4.5169 rad) and beyond the Panda's (3.7525): the robot driven
    q_fr3 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 3.9, 0.7854])
    r = arm.ok(command="move_joints", q=q_fr3.tolist(), speed=0.6)
    assert r.ok and r.status == "done", r
    assert np.abs(np.array(r.q) - q_fr3).max() < 0.01


def test_refused_targets_do_not_move(arm: Arm) -> None:
    p0, _ = arm.mean_pose()
    e = arm.err(command="move_pose", position=[0.5, 0.0, -0.1], quaternion_xyzw=[1, 0, 0, 0])
    assert e.error == "OutsideWorkspace" and "-0.1" in e.message
    e = arm.err(command="move_joints", q=[2.9, 0, 0, -1.5, 0, 1.5, 0])
    assert e.error == "OutsideJointLimits" and "joint 1" in e.message
    e = arm.err(command="move_joints", q=[2.5, 0, 0, -1.5708, 0, 1.5708, 0.7854])  # behind the base
    assert e.error == "OutsideWorkspace"
    e = arm.err(command="move_pose", position=[0.84, 0.55, 0.85], quaternion_xyzw=[1, 0, 0, 0])
    assert e.error == "Unreachable"
    e = arm.err(command="move_joints", q=[0, 0, 0])
    assert e.error == "PayloadError"
    reply = arm.command(command="move_joints", q=[float("nan")] * 7)
    assert reply.err is not None
    e = (
        arm.err(command="pick_place", place_position=[0.5, 0.2, 0.3])
        if not _has("sofia_arm.pick_place")
        else None
    )
    assert e is None or (e.error == "Unavailable" and "pick_place" in e.message)
    p1, _ = arm.mean_pose()
    assert np.linalg.norm(p1 - p0) < 1e-3


def _has(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None


def test_stop_halts_motion(arm: Arm) -> None:
    assert arm.ok(command="move_joints", q=HOME.tolist(), speed=0.6).ok
    t, out = in_thread(arm, command="move_joints", q=Q_FAR.tolist(), speed=0.15)
    time.sleep(1.0)
    stop = arm.ok(command="stop")
    t.join(30)
    assert stop.ok and stop.status == "done", stop
    assert out and out[0].status == "stopped", out
    p_stop, _ = arm.mean_pose(0.1)
    time.sleep(0.5)
    p_later, _ = arm.mean_pose(0.1)
    assert np.linalg.norm(p_later - p_stop) < 1e-3  # it stays
    assert np.linalg.norm(p_later - panda_fk(Q_FAR)[:3, 3]) > 0.02  # and never got there
    assert np.linalg.norm(p_later - panda_fk(HOME)[:3, 3]) > 0.005  # but it had started


def test_new_command_preempts(arm: Arm) -> None:
    t, out = in_thread(arm, command="move_joints", q=Q_FAR.tolist(), speed=0.15)
    time.sleep(0.8)
    r = arm.ok(command="move_joints", q=Q_A.tolist(), speed=0.6)
    t.join(30)
    assert out and out[0].status == "preempted" and "move_joints" in out[0].reason, out
    assert r.ok, r
    assert_at(arm, panda_fk(Q_A))


def test_gripper_error_blocks_motion(arm: Arm) -> None:
    pub = arm.session.declare_publisher(arm.keys.gripper_state)
    bad = GripperState(stamp_ns=time.time_ns(), connected=True, status="error", error="overload")
    for _ in range(5):
        pub.put(bad.to_json_bytes())
        time.sleep(0.05)
    e = arm.err(command="home")
    assert e.error == "NotReady" and "gripper" in e.message and "overload" in e.message
    good = GripperState(stamp_ns=time.time_ns(), connected=True, status="ok")
    pub.put(good.to_json_bytes())
    time.sleep(0.2)
    assert arm.ok(command="home", speed=0.6).ok
    pub.undeclare()


def test_robot_lost_mid_motion_then_recover(arm: Arm) -> None:
    t, out = in_thread(arm, command="move_joints", q=Q_FAR.tolist(), speed=0.15, timeout_s=30)
    time.sleep(0.8)
    host = arm.sim.host
    arm.sim.kill()
    t.join(40)
    assert out and out[0].status == "failed" and out[0].reason, out
    deadline = time.monotonic() + 20
    while arm.latest_state().mode not in ("disconnected", "error") and time.monotonic() < deadline:
        pass
    state = arm.latest_state()
    assert state.mode in ("disconnected", "error") and state.errors, state
    e = arm.err(command="home")
    assert e.error == "NotReady"

    from sofia_arm.sim import start_sim

    arm.sim = start_sim(hostname=host)
    r = arm.ok(command="recover", timeout_s=30)
    assert r.ok, r
    assert arm.latest_state().errors == []
    r = arm.ok(command="move_joints", q=Q_A.tolist(), speed=0.6)
    assert r.ok, r
    assert_at(arm, panda_fk(Q_A))
    assert json.loads(json.dumps(r.model_dump()))["status"] == "done"
    assert pytest.approx(0) == 0


def test_cli_prints_text_and_json(arm: Arm) -> None:
    """`sofia arm state` / `sofia arm stop` against the running service: text for people, --json for
    machines (one object)."""
    env = dict(os.environ, SOFIA_ROBOT=arm.keys.robot)

    def sofia(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([SOFIA, "arm", *args], env=env, capture_output=True, text=True, timeout=120)

    state, state_json = sofia("state"), sofia("state", "--json")
    assert state.returncode == 0 and state.stdout.startswith("arm: connected, mode "), (
        state.stdout + state.stderr
    )
    assert "errors: none" in state.stdout and " rad" in state.stdout
    assert json.loads(state_json.stdout)["connected"] is True, state_json.stdout
    stop, stop_json = sofia("stop"), sofia("stop", "--json")
    assert stop.returncode == 0 and stop.stdout.startswith("stop: done"), stop.stdout + stop.stderr
    assert ArmResult.model_validate_json(stop_json.stdout).status == "done", stop_json.stdout
