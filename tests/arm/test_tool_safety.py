"""The tool-aware rules without a robot: the fingers above the surface at the target and along the
way, the surface from the board file, and pick and place checked pose by pose before it moves."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_arm.config import ArmConfig
from sofia_arm.errors import BelowSurface, OutsideWorkspace, TargetRefused, Unreachable
from sofia_arm.pick_place import PLACE_CLEARANCE_M, check_pick_place, place_of, plan_poses
from sofia_arm.poses import solve_ik
from sofia_arm.safety import Safety
from sofia_arm.tool import line_path
from sofia_schemas.kinematics import panda_fk
from sofia_schemas.messages import ArmCommand, PickTarget
from sofia_schemas.transforms import make_transform

HOME = np.array(ArmConfig().home_q)
DOWN = np.array([1.0, 0.0, 0.0, 0.0])  # flange z axis along -z of the base: fingers down
TARGET = PickTarget(
    stamp_ns=1, object_center=(0.55, 0.12, 0.025), grasp_translation=(0.55, 0.12, 0.225),
    pregrasp_translation=(0.55, 0.12, 0.325), rotation_xyzw=(1.0, 0.0, 0.0, 0.0), yaw=0.0, opening_mm=60.0,
    fingertip_offset_m=0.2, pregrasp_height_m=0.1,
)  # fmt: skip


def down_at(x: float, y: float, z: float) -> np.ndarray:
    return make_transform(np.array([x, y, z]), DOWN)


def test_fingers_below_the_surface_are_refused_a_bare_flange_is_not() -> None:
    safety = Safety(ArmConfig())
    with pytest.raises(BelowSurface, match=r"move_pose target: the fingers .* would reach \[.*-0\.12\] m"):
        safety.check_pose_target(down_at(0.5, 0.0, 0.08), HOME)
    with pytest.raises(BelowSurface, match=r"margin of 0\.005 m: z must stay >= 0\.0050 m"):
        safety.check_pose_target(down_at(0.5, 0.0, 0.203), HOME)
    q = safety.check_pose_target(down_at(0.5, 0.0, 0.21), HOME)
    np.testing.assert_allclose(panda_fk(q)[:3, 3], [0.5, 0.0, 0.21], atol=1e-5)
    bare = Safety(ArmConfig(tool="flange"))
    bare.check_pose_target(down_at(0.5, 0.0, 0.08), HOME)
    with pytest.raises(BelowSurface, match="the flange would reach"):
        Safety(ArmConfig(tool="flange", surface_z=0.1, workspace_min=(0.15, -0.6, 0.0))).check_pose_target(
            down_at(0.5, 0.0, 0.08), HOME
        )


def test_joint_targets_are_checked_at_the_target_and_on_the_way() -> None:
    safety = Safety(ArmConfig())
    low = solve_ik(
        down_at(0.5, 0.0, 0.12), HOME, safety.reach.__class__()
    ).q  # flange 12 cm up: tips in the table
    with pytest.raises(BelowSurface, match=r"move_joints target: the fingers"):
        safety.check_joint_target(low)
    T_a = make_transform(np.array([0.45, 0.0, 0.16]), Rotation.from_euler("y", 95, degrees=True).as_quat())
    T_b = make_transform(np.array([0.55, 0.0, 0.16]), Rotation.from_euler("y", 265, degrees=True).as_quat())
    safety.check_tool(T_a)
    safety.check_tool(T_b)  # both ends: fingers nearly horizontal, above the table ...
    with pytest.raises(BelowSurface, match="on the way"):  # ... but they turn down through it between them
        safety.check_tool(line_path(T_a, T_b), "on the way")


def test_the_surface_comes_from_the_board_file(tmp_path: Path) -> None:
    board = tmp_path / "board.yaml"
    board.write_text("center: [0.5, 0.0]\nsurface_z: 0.05\n")
    safety = Safety(ArmConfig(board_file=board))
    assert safety.surface.z == 0.05 and "board" in safety.surface.source
    safety.check_pose_target(down_at(0.5, 0.0, 0.26), HOME)
    with pytest.raises(BelowSurface, match=r"board .*surface_z = 0.05 m"):
        safety.check_pose_target(down_at(0.5, 0.0, 0.25), HOME)


def _pick_place(**place: object) -> ArmCommand:
    return ArmCommand(command="pick_place", target=TARGET, **place)  # type: ignore[arg-type]


def test_pick_place_is_checked_pose_by_pose_before_it_moves() -> None:
    safety = Safety(ArmConfig())
    planned = check_pick_place(_pick_place(place_position=(0.45, -0.25, 0.25)), TARGET, safety, HOME)
    assert list(planned) == ["pregrasp", "descend", "lift", "move", "lower", "retreat"]
    np.testing.assert_allclose(panda_fk(planned["lower"])[:3, 3], [0.45, -0.25, 0.25], atol=1e-5)
    with pytest.raises(BelowSurface, match=r"pick_place pose 'place' \(lower\): the fingers .* -0.08\]"):
        check_pick_place(_pick_place(place_position=(0.45, -0.25, 0.12)), TARGET, safety, HOME)
    with pytest.raises(BelowSurface, match=r"pick_place pose 'above_place' \(move\): the fingers"):
        check_pick_place(_pick_place(place_position=(0.45, -0.25, 0.07)), TARGET, safety, HOME)
    with pytest.raises(
        OutsideWorkspace, match=r"pick_place pose 'above_place' \(move\): flange position \[1.2"
    ):
        check_pick_place(_pick_place(place_position=(1.2, 0.0, 0.3)), TARGET, safety, HOME)
    with pytest.raises(Unreachable, match=r"pick_place pose 'above_place' \(move\)"):
        check_pick_place(_pick_place(place_position=(0.84, 0.59, 0.75)), TARGET, safety, HOME)
    deep = TARGET.model_copy(update={"grasp_translation": (0.55, 0.12, 0.15)})
    with pytest.raises(BelowSurface, match=r"pick_place pose 'grasp' \(descend\)"):
        check_pick_place(_pick_place(place_position=(0.45, -0.25, 0.25)), deep, safety, HOME)


def test_a_place_given_as_where_the_object_ends_up() -> None:
    safety = Safety(ArmConfig())
    B = np.array([0.42, -0.2, 0.0])
    cmd = _pick_place(place_object=tuple(B))
    place = place_of(cmd, TARGET, safety)
    # fingers down: the flange above B by the fingertip offset plus the object's centre height
    np.testing.assert_allclose(
        place["position"], B + np.array([0, 0, 0.2 + 0.025 + PLACE_CLEARANCE_M]), atol=1e-12
    )
    poses = plan_poses(TARGET, place["position"], None)
    tips = poses["place"][:3, 3] + poses["place"][:3, 2] * 0.2
    np.testing.assert_allclose(tips[:2], B[:2], atol=1e-12)
    check_pick_place(cmd, TARGET, safety, HOME)
    with pytest.raises(TargetRefused, match="below the surface"):
        place_of(_pick_place(place_object=(0.42, -0.2, -0.05)), TARGET, safety)
    with pytest.raises(ValueError, match="one of place_position"):
        ArmCommand(command="pick_place", place_position=(0.4, 0, 0.3), place_object=(0.4, 0, 0))
