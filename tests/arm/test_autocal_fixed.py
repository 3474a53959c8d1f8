"""Autonomous eye-to-hand calibration in one process: a kinematic Panda with a ball on its flange,
a fixed simulated D435 (the camera service's eye-to-hand cell), the calibrator library."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_arm import autocal_fixed as fixed
from sofia_arm.autocal import D435_K, AutocalError, AutocalOptions, FixedAutocal
from sofia_arm.autocal_io import LocalCalibrator, Progress
from sofia_arm.autocal_sim import BallEye, KinematicArm
from sofia_arm.poses import Reach, in_image
from sofia_camera.sim_fixed import DEFAULT_T_BASE_CAM
from sofia_replay.synth.camera import look_at
from sofia_schemas.transforms import apply, invert, rotation_angle

from ..conftest import gap_mm_deg

# a mount other than the default: left of the robot, higher, looking down at the workspace
T_BASE_CAM = look_at(np.array([0.55, 0.75, 0.8]), np.array([0.35, 0.0, 0.45]), np.array([-1.0, 0.2, 0.0]))
BALL_FLANGE = (0.02, -0.015, 0.11)  # off the flange axis
RADIUS = 0.025


def _run(T_base_cam: np.ndarray, **opts: object) -> tuple[FixedAutocal, KinematicArm]:
    arm = KinematicArm()
    eye = BallEye(arm, T_base_cam, BALL_FLANGE, RADIUS, seed=2)
    options = AutocalOptions.from_dict({"setup": "eye-to-hand", **opts})
    return FixedAutocal(arm, eye, LocalCalibrator("eye-to-hand"), options, Progress(None, None)), arm


@pytest.mark.parametrize("T_base_cam", [pytest.param(T_BASE_CAM, id="left-high"),
                                        pytest.param(DEFAULT_T_BASE_CAM, id="default-mount")])  # fmt: skip
def test_eye_to_hand_autocal_finds_the_fixed_camera_and_the_ball(T_base_cam: np.ndarray) -> None:
    run, _ = _run(T_base_cam, ball_radius=RADIUS)
    out = run.run()
    assert out.result is not None, [p.line() for p in run.progress.phases]
    T_est = np.array(out.result.matrix)
    err_mm, err_deg = gap_mm_deg(T_est, T_base_cam)
    assert err_mm < 1.0 and err_deg < 0.2, (err_mm, err_deg, [p.line() for p in run.progress.phases])
    assert 1e3 * np.linalg.norm(np.array(out.result.target_base) - BALL_FLANGE) < 1.0
    assert out.result.parent_frame == "panda_link0"  # T_base_cam, not T_flange_cam
    assert "below 1.0 mm" in out.stop_reason and out.poses <= run.opts.max_poses
    assert any(p.name == "find camera" and p.status == "done" for p in run.progress.phases)
    assert any(p.name == "find ball" and p.reason.startswith("ball at") for p in run.progress.phases)


def test_the_rough_start_recovers_camera_and_ball_from_exact_views() -> None:
    T_start = KinematicArm().T_base_flange()
    T_bf = np.array([T_start] + [T for _, T in fixed.start_moves(T_start)])
    p_base = apply(T_bf, np.broadcast_to(np.array(BALL_FLANGE), (len(T_bf), 3)))
    p_cam = apply(invert(T_BASE_CAM), p_base)
    rough = fixed.rough_fixed(T_bf, p_cam)
    assert rough is not None
    np.testing.assert_allclose(rough[0], T_BASE_CAM, atol=1e-9)
    np.testing.assert_allclose(rough[1], BALL_FLANGE, atol=1e-9)
    assert fixed.rough_fixed(T_bf[4:], p_cam[4:]) is None  # turns only: no rotation from shifts


def test_planned_views_put_the_ball_in_front_of_the_camera_and_the_flange_in_reach() -> None:
    reach = Reach()
    R_start = KinematicArm().T_base_flange()[:3, :3]
    T = fixed.fixed_candidates(T_BASE_CAM, np.array(BALL_FLANGE), R_start, reach, (0.45, 0.9), D435_K,
                               (640, 480), 40.0)  # fmt: skip
    assert len(T) > 50
    p_cam = apply(invert(T_BASE_CAM)[None] @ T, np.broadcast_to(np.array(BALL_FLANGE), (len(T), 3)))
    assert np.all(in_image(p_cam, D435_K, (640, 480), 39.0))
    assert np.all((np.linalg.norm(p_cam, axis=1) > 0.449) & (np.linalg.norm(p_cam, axis=1) < 0.901))
    assert np.all(reach.in_box(T[:, :3, 3]))
    tilts = np.degrees([rotation_angle(R_start.T @ R) for R in T[:, :3, :3]])
    assert tilts.max() > 30.0  # the orientations vary: the rotation is observable


def test_a_ball_out_of_view_at_the_start_is_a_clear_error() -> None:
    away = look_at(np.array([0.4, -0.9, 0.3]), np.array([0.4, -2.0, 0.3]), np.array([1.0, 0.0, 0.0]))
    run, _ = _run(away)
    with pytest.raises(AutocalError, match="find ball: the fixed camera does not see the ball"):
        run.run()


def test_eye_to_hand_options_are_checked() -> None:
    with pytest.raises(ValueError, match="setup must be one of"):
        AutocalOptions.from_dict({"setup": "eye-on-table"})
    with pytest.raises(ValueError, match="ball_radius"):
        AutocalOptions.from_dict({"setup": "eye-to-hand", "ball_radius": 0.5})
    assert AutocalOptions.from_dict({"setup": "eye-to-hand"}).distance_m == (0.45, 0.9)
    q = Rotation.from_matrix(DEFAULT_T_BASE_CAM[:3, :3]).as_quat()
    opts = AutocalOptions.from_dict({"setup": "eye-to-hand", "guess": [*DEFAULT_T_BASE_CAM[:3, 3], *q]})
    assert opts.guess is not None
