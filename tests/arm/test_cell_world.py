"""The simulated cell with a camera mount, board pose and object placement of its own (not the
demo's): the arm surveys the board, picks the object at A, sets it down at B, and the camera's
next detection sees it at B and nothing at A. The world the camera renders, the emulated
gripper's fingers and the arm's load share one world file; each service is its own process."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import zenoh
from scipy.spatial.transform import Rotation
from sofia_runtime.client import ask
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas import Board
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ArmCommand, ArmResult
from sofia_schemas.sim_world import ENV_SIM_WORLD, read_world

from ..conftest import Proc
from .conftest import start_cell

# a board turned 10 degrees and moved left, a camera turned 100 degrees on the flange and tilted
# 5 degrees, another seed for the object (the demo: the default board and mount, seed 0)
BOARD = "center: [0.47, 0.07]\nsurface_z: 0.0\nyaw: 0.17\n"
CAM_Q = Rotation.from_euler("zx", [100.0, -5.0], degrees=True).as_quat()
CAM_T = np.array([0.06, -0.012, 0.05])
SEED = "5"


def test_survey_pick_place_and_the_object_seen_at_b(
    sofia_proc: Callable[..., Proc], robot_id: str, tmp_path: Path
) -> None:
    board_file, world_file, transform = tmp_path / "board.yaml", tmp_path / "world.json", tmp_path / "T.json"
    board_file.write_text(BOARD)
    T_fc = np.eye(4)
    T_fc[:3, :3], T_fc[:3, 3] = Rotation.from_quat(CAM_Q).as_matrix(), CAM_T
    transform.write_text(json.dumps({"matrix": T_fc.tolist()}))
    env = {ENV_SIM_WORLD: str(world_file)}
    cam = " ".join(f"{v:.9f}" for v in (*CAM_T, *CAM_Q))
    board = ["--board", str(board_file), "--transform", str(transform)]
    procs = start_cell(sofia_proc, env, ["--sim-board", str(board_file), "--sim-T-flange-cam", cam, "--sim-seed", SEED],
                       board, board)  # fmt: skip
    world = read_world(world_file)
    assert world is not None and len(world.objects) == 1
    A = world.objects[0].centre()
    # B: the centre of the field farthest from A (configured board), on the surface
    board = Board.from_file(board_file)
    fields = np.array([board.field_center_base(r, c) for r in range(board.rows) for c in range(board.cols)])
    B = fields[np.argmax(np.linalg.norm(fields[:, :2] - A[:2], axis=1))]
    B = np.array([B[0], B[1], board.surface_z])
    cmd = ArmCommand(command="pick_place", place_object=tuple(B), speed=1.0, timeout_s=600)  # type: ignore[arg-type]
    with zenoh.open(zenoh_config()) as session:
        res = ask(session, Keys(robot_id).arm_command, ArmResult, cmd.model_dump_json(), timeout=660)
    phases = [p.name for p in res.phases]
    assert res.ok, (res.reason, [p.line() for p in res.phases], procs[1].log()[-3000:])
    lines = [p.line() for p in res.phases]
    # a second view centred on the object when the survey saw it cut by the image border
    assert phases[0] == "survey" and phases[-2:] == ["verify", "seen at B"], lines
    assert phases.index("target") < phases.index("check") < phases.index("open"), lines
    seen = res.details["seen"]
    assert seen["placed_error_mm"] <= 5.0 and seen["a_empty"], (seen, lines)
    print("\n".join(lines))
    offset = res.details["target"]["fingertip_offset_m"]
    grasp_err_mm = 1e3 * np.linalg.norm(
        np.array(res.details["reached"]["grasp"]["position"]) - A - [0, 0, offset]
    )
    assert grasp_err_mm < 3.0, grasp_err_mm
    after = read_world(world_file)
    assert after is not None and not after.objects[0].held
    resting = after.objects[0].centre()
    assert np.linalg.norm(resting[:2] - B[:2]) < 0.005, (resting, B)  # the world agrees with the camera
