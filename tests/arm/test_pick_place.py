"""Pick and place: the phase poses, and the whole cell in simulation: franky-sim behind the arm
service, the simulated D435 rendering the board from the live flange pose, the detector, the
emulated gripper, each its own process over Zenoh."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import zenoh
from sofia_arm.pick_place import LIFT_M, plan_poses
from sofia_runtime.client import ask
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ArmCommand, ArmResult, PickTarget

from ..conftest import SOFIA, Proc

TARGET = PickTarget(
    stamp_ns=1, object_center=(0.6, 0.1, 0.03), grasp_translation=(0.6, 0.1, 0.23),
    pregrasp_translation=(0.6, 0.1, 0.33), rotation_xyzw=(1.0, 0.0, 0.0, 0.0), yaw=0.0, opening_mm=60.0,
    fingertip_offset_m=0.2, pregrasp_height_m=0.1,
)  # fmt: skip


def test_phase_poses_go_down_and_up_along_the_base_z_axis() -> None:
    poses = plan_poses(TARGET, np.array([0.4, -0.2, 0.25]), None)
    np.testing.assert_allclose(poses["grasp"][:3, 3], TARGET.grasp_translation)
    np.testing.assert_allclose(poses["pregrasp"][:3, 3], TARGET.pregrasp_translation)
    np.testing.assert_allclose(poses["lift"][:3, 3] - poses["grasp"][:3, 3], [0, 0, LIFT_M])
    np.testing.assert_allclose(poses["above_place"][:3, 3] - poses["place"][:3, 3], [0, 0, LIFT_M])
    for T in poses.values():  # the grasp orientation is kept (fingers down, object's yaw)
        np.testing.assert_allclose(T[:3, :3], poses["grasp"][:3, :3])
        np.testing.assert_allclose(T[:3, 2], [0, 0, -1], atol=1e-12)
    turned = plan_poses(TARGET, np.array([0.4, -0.2, 0.25]), np.array([0.0, 1.0, 0.0, 0.0]))
    np.testing.assert_allclose(turned["place"][:3, :3], np.diag([-1.0, 1.0, -1.0]), atol=1e-12)


def sim_truth(*args: str) -> dict:
    out = subprocess.run(
        [SOFIA, "camera", "sim-truth", *args, "--json"], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_pick_and_place_in_the_simulated_cell(
    sofia_proc: Callable[..., Proc], robot_id: str, tmp_path: Path
) -> None:
    truth = sim_truth("--sim-scene", "board")
    obj = truth["objects"][0]
    width_mm = 1e3 * min(obj["extents"][0], obj["extents"][1])
    transform = tmp_path / "T_flange_cam.json"
    transform.write_text(json.dumps({"matrix": truth["T_flange_cam"]}))
    procs = [
        sofia_proc("arm", "serve", "--sim", "--max-speed", "1.0"),
        # 6 frames a second: the renderer leaves CPU to franky-sim, whose clock slows on a loaded host
        sofia_proc("camera", "serve", "--sim", "--sim-scene", "board", "--fps", "6"),
        sofia_proc("detector", "serve", "--transform", str(transform)),
        sofia_proc("gripper", "serve", "--emulate", "--object-width", f"{width_mm:.1f}"),
    ]
    procs[0].wait_for_log("connected to the robot", 120)
    procs[1].wait_for_log("camera ready", 120)  # the pick target needs clouds
    procs[2].wait_for_log("detector ready", 120)
    keys = Keys(robot_id)
    place = (0.45, -0.25, 0.25)
    # about 60 s of the simulator's clock, which runs at 0.3-0.9 x wall time depending on the host's load
    cmd = ArmCommand(command="pick_place", place_position=place, speed=1.0, timeout_s=480)
    with zenoh.open(zenoh_config()) as session:
        res = ask(session, keys.arm_command, ArmResult, cmd.model_dump_json(), timeout=540)
    phases = {p.name: p for p in res.phases}
    assert res.ok, (res.reason, [(p.name, p.status, p.reason) for p in res.phases], procs[0].log()[-3000:])
    assert list(phases) == ["target", "check", "open", "pregrasp", "descend", "grasp", "lift", "move", "lower", "release",
                            "retreat"]  # fmt: skip
    assert "grasped True" in phases["grasp"].reason
    reached = res.details["reached"]
    offset = res.details["target"]["fingertip_offset_m"]
    grasp_expected = np.array(obj["center"]) + np.array([0.0, 0.0, offset])  # fingers down: flange above
    err_mm = 1e3 * np.linalg.norm(np.array(reached["grasp"]["position"]) - grasp_expected)
    assert err_mm < 2.0, err_mm
    assert 1e3 * np.linalg.norm(np.array(reached["lower"]["position"]) - place) < 1.0
