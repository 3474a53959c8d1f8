"""One call and one command for every target and set-up: the same Calibration, message and files."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sofia_calibrator import calibrate, calibrate_target, to_message, to_yaml
from sofia_calibrator.errors import InputMismatch
from sofia_calibrator.fitting.simulate import make_eye_to_hand, make_problem

from ..conftest import SOFIA


def _ball(centre: np.ndarray, radius: float, rng: np.random.Generator, n: int = 1500) -> np.ndarray:
    """(n, 3) noisy points of the half of a ball facing the camera, camera frame, metres."""
    d = rng.standard_normal((4 * n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = d[d @ centre < 0][:n]
    return np.asarray(centre + radius * d + rng.standard_normal((len(d), 3)) * 3e-4)


def _eye_to_hand_poses(seed: int) -> tuple[Any, np.ndarray]:
    """An exact eye-to-hand problem of 10 poses and its target poses in the camera, (10, 4, 4): the
    target frame at the ball's place on the flange, axes as the flange's."""
    pr = make_eye_to_hand(10, np.random.default_rng(seed), noise_scale=0.0)
    T_flange_target = np.eye(4)
    T_flange_target[:3, 3] = pr.p_flange
    return pr, np.linalg.inv(pr.T_base_cam) @ pr.T_base_flange @ T_flange_target


def test_the_blob_call_is_calibrate() -> None:
    pr = make_problem(10, np.random.default_rng(20))
    a = calibrate_target("blob", T_base_flange=pr.T_base_flange, p_cam=pr.p_cam)
    b = calibrate(pr.p_cam, pr.T_base_flange)
    np.testing.assert_allclose(a.T_flange_cam, b.T_flange_cam)
    assert (a.parent_frame, a.child_frame) == (b.parent_frame, b.child_frame)


def test_a_ball_on_the_flange_calibrates_a_fixed_camera() -> None:
    rng = np.random.default_rng(21)
    pr = make_eye_to_hand(12, rng, noise_scale=0.0)
    clouds = [_ball(c, 0.025, rng) for c in pr.p_cam_true]
    cal = calibrate_target(
        "sphere", "eye-to-hand", T_base_flange=pr.T_base_flange, clouds_cam=clouds, radius_m=0.025
    )
    assert np.linalg.norm(cal.T_flange_cam[:3, 3] - pr.T_base_cam[:3, 3]) < 2e-3
    assert np.linalg.norm(cal.p_base - pr.p_flange) < 1e-3
    assert to_message(cal).parent_frame == "panda_link0"


def test_pose_targets_give_the_same_message() -> None:
    pr, T_cam_target = _eye_to_hand_poses(22)
    cal = calibrate_target("poses", "eye-to-hand", T_base_flange=pr.T_base_flange, T_cam_target=T_cam_target)
    np.testing.assert_allclose(cal.T_flange_cam, pr.T_base_cam, atol=1e-6)
    text = to_yaml(to_message(cal))
    assert "parent_frame: panda_link0" in text and "pose target" in text and "passes: true" in text


def test_robot_world_hand_eye_starts_and_baselines_recover_exact_poses() -> None:
    from sofia_calibrator.targets.poses import hand_eye_from_poses, opencv_hand_eye

    pr, T_cam_target = _eye_to_hand_poses(23)
    A = np.linalg.inv(pr.T_base_flange)  # eye-to-hand: the eye-in-hand problem of the inverted poses
    base = opencv_hand_eye(A, T_cam_target)
    for name in ("RW_SHAH", "RW_LI"):  # calibrateRobotWorldHandEye, with the target as its world
        np.testing.assert_allclose(base[name], pr.T_base_cam, atol=1e-6, err_msg=name)
    fit = hand_eye_from_poses(pr.T_base_flange, T_cam_target, setup="eye-to-hand")
    assert {"RW_SHAH", "RW_LI", "TSAI"} <= set(fit.baselines)


def test_unknown_targets_and_missing_inputs_say_so() -> None:
    pr = make_problem(6, np.random.default_rng(23))
    with pytest.raises(InputMismatch, match="'apriltag' needs images"):
        calibrate_target("apriltag", T_base_flange=pr.T_base_flange)
    with pytest.raises(InputMismatch, match="needs images"):
        calibrate_target("charuco", T_base_flange=pr.T_base_flange)
    with pytest.raises(InputMismatch, match="target must be one of"):
        calibrate_target("laser", T_base_flange=pr.T_base_flange)
    with pytest.raises(InputMismatch, match="needs clouds_cam"):
        calibrate_target("sphere", T_base_flange=pr.T_base_flange)


def test_the_command_calibrates_a_sphere_eye_to_hand(tmp_path: Path) -> None:
    import open3d as o3d
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(24)
    pr = make_eye_to_hand(9, rng, noise_scale=0.0)
    names = []
    for i, c in enumerate(pr.p_cam_true):
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(_ball(c, 0.03, rng) * 1e3))  # millimetres
        names.append(str(tmp_path / f"view{i}.pcd"))
        o3d.io.write_point_cloud(names[-1], pc)
    T = pr.T_base_flange
    rows = np.c_[Rotation.from_matrix(T[:, :3, :3]).as_euler("xyz"), 1e3 * T[:, :3, 3]]
    np.savetxt(tmp_path / "poses.dat", rows, delimiter=",")
    out = subprocess.run(
        [SOFIA, "calibrate", "--target", "sphere", "--setup", "eye-to-hand", "--clouds", *names,
         "--cloud-unit", "0.001", "--euler-poses", str(tmp_path / "poses.dat"), "--json"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    msg = json.loads(out.stdout)
    assert msg["parent_frame"] == "panda_link0"
    assert np.abs(np.array(msg["matrix"]) - pr.T_base_cam).max() < 3e-3
    bad = subprocess.run([SOFIA, "calibrate", "--target", "sphere", "--clouds", *names[:3], "--euler-poses",
                          str(tmp_path / "poses.dat")], capture_output=True, text=True, timeout=120)  # fmt: skip
    assert bad.returncode != 0 and "3 clouds but 9 flange poses" in bad.stderr
