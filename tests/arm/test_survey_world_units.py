"""The survey's views and the simulated world's rules without processes: the camera sees the whole
board from the survey pose, an object is between the fingers only at the fingertips, carried
with the flange and set down on the board below them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_arm.config import ArmConfig
from sofia_arm.poses import in_image
from sofia_arm.safety import Safety
from sofia_arm.survey import CAMERA_K, IMAGE_SIZE, board_corners, survey_views
from sofia_arm.world import WorldKeeper, between, resting_pose, width_across
from sofia_schemas import Board
from sofia_schemas.messages import GripperState
from sofia_schemas.sim_world import WorldObject, WorldState, read_world, write_world
from sofia_schemas.transforms import apply, invert

HOME = np.array(ArmConfig().home_q)


def _T(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


@pytest.mark.parametrize(
    ("centre", "yaw", "cam_deg"), [((0.5, 0.0), 0.0, (90, -8)), ((0.42, 0.12), 0.4, (0, 10))]
)
def test_survey_views_see_every_corner_of_the_board_and_pass_the_rules(
    centre: tuple[float, float], yaw: float, cam_deg: tuple[float, float]
) -> None:
    board = Board(center=centre, yaw=yaw)
    T_fc = _T(Rotation.from_euler("zx", cam_deg, degrees=True).as_matrix(), np.array([0.06, 0.0, 0.05]))
    views = survey_views(board, T_fc)
    assert len(views) > 0
    corners = board_corners(board)
    for T_bf in views:
        p_cam = apply(invert(T_bf @ T_fc), corners)
        assert in_image(p_cam, CAMERA_K, IMAGE_SIZE, 1.0).all()
    safety = Safety(ArmConfig())
    ok = 0
    for T_bf in views[:8]:
        try:
            safety.check_plan("pick_place", [("survey", "survey", "joints", T_bf)], HOME)
            ok += 1
        except ValueError:
            pass
    assert ok > 0  # a reachable, safe survey pose exists for these boards


def _box(centre: np.ndarray, yaw: float, extents: tuple[float, float, float]) -> WorldObject:
    T = _T(Rotation.from_euler("z", yaw).as_matrix(), centre)
    return WorldObject(id=0, shape="box", extents=extents, colour=(230, 200, 40), T_base_obj=T.tolist())


def test_between_the_fingers_and_the_width_they_close_on() -> None:
    obj = _box(np.array([0.5, 0.1, 0.02]), 0.0, (0.08, 0.04, 0.04))
    down = np.diag([1.0, -1.0, -1.0])  # flange y along -base y: the fingers close across the 4 cm
    T = _T(down, np.array([0.5, 0.1, 0.22]))
    assert between(obj, T[:3, 3] + T[:3, 2] * 0.2)
    assert not between(obj, np.array([0.5, 0.16, 0.02]))  # 6 cm aside
    assert not between(obj, np.array([0.5, 0.1, 0.08]))  # above it
    assert width_across(obj, T) == pytest.approx(0.04)
    turned = _T(Rotation.from_euler("z", np.pi / 2).as_matrix() @ down, T[:3, 3])
    assert width_across(obj, turned) == pytest.approx(0.08)


def test_the_keeper_carries_the_grasped_object_and_sets_it_down_below_the_fingertips(tmp_path: Path) -> None:
    T_board = _T(Rotation.from_euler("xz", [0.02, 0.3]).as_matrix(), np.array([0.5, 0.0, 0.01]))
    obj = _box(np.zeros(3), 0.3, (0.06, 0.04, 0.05))
    obj.T_base_obj = (T_board @ _T(np.eye(3), np.array([0.05, 0.02, 0.025]))).tolist()
    path = tmp_path / "world.json"
    write_world(path, WorldState(T_base_board=T_board.tolist(), objects=[obj]))
    keeper = WorldKeeper(path, 0.2)
    down = Rotation.from_euler("z", 0.3).as_matrix() @ np.diag([1.0, -1.0, -1.0])
    A = obj.centre()
    keeper.on_pose(_T(down, A + np.array([0, 0, 0.2])))
    keeper.gripper = GripperState(stamp_ns=1, connected=True, status="ok", opening_mm=70.0)
    keeper.tick()
    w = read_world(path)
    assert w is not None and w.between_fingers == 0 and w.between_width_mm == pytest.approx(40.0, abs=0.5)
    keeper.gripper = GripperState(stamp_ns=2, connected=True, status="ok", opening_mm=39.0, grasped=True)
    keeper.tick()
    B = np.array([0.45, -0.12, 0.0])
    keeper.on_pose(_T(down, B + np.array([0, 0, 0.3])))  # carried 5 cm above the board
    keeper.tick()
    w = read_world(path)
    assert w is not None and w.objects[0].held
    np.testing.assert_allclose(w.objects[0].centre(), B + np.array([0, 0, 0.1]), atol=1e-9)
    keeper.gripper = GripperState(stamp_ns=3, connected=True, status="ok", opening_mm=70.0)
    keeper.tick()
    w = read_world(path)
    assert w is not None and not w.objects[0].held
    T_rest = resting_pose(w.objects[0], T_board)
    np.testing.assert_allclose(w.objects[0].pose(), T_rest, atol=1e-9)
    p_board = invert(T_board) @ np.r_[w.objects[0].centre(), 1.0]
    assert p_board[2] == pytest.approx(0.025)  # resting on the board: half its height above it
    np.testing.assert_allclose(w.objects[0].centre()[:2], B[:2], atol=0.003)  # below the fingertips (tilt)


def test_a_low_object_is_held_higher_within_its_height() -> None:
    from sofia_arm.survey import GRASP_CLEARANCE_M, pick_of
    from sofia_schemas.messages import DetectedObject

    safety = Safety(ArmConfig())

    def obj(z: float, h: float) -> DetectedObject:
        return DetectedObject(center=(0.5, 0.0, z), centroid=(0.5, 0.0, z), extents=(0.05, 0.04, h), yaw=0.0,
                              field=None, allowed=True, n_points=500, confidence=0.95)  # fmt: skip

    tips_z = pick_of(obj(0.025, 0.05), 1, safety).grasp_translation[2] - 0.2
    assert tips_z == pytest.approx(0.025)  # centre high enough: held at its centre
    tips_z = pick_of(obj(0.004, 0.05), 1, safety).grasp_translation[2] - 0.2  # a board lower than configured
    assert tips_z == pytest.approx(safety.surface.lowest_allowed + GRASP_CLEARANCE_M)
    tips_z = pick_of(obj(0.002, 0.012), 1, safety).grasp_translation[2] - 0.2  # too flat: left at its centre
    assert tips_z == pytest.approx(0.002)  # ... and refused by the rules before any motion
