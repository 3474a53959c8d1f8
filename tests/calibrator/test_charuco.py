"""ChArUco board target: rendered views detected by OpenCV's aruco module, the board poses recovered,
the hand-eye transform as accurate as OpenCV's best method on the same views; a view without the
board says which."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator.any_target import calibrate_target
from sofia_calibrator.fitting.diagnostics import error6
from sofia_calibrator.targets.poses import hand_eye_from_poses

from ..conftest import SOFIA
from .conftest import rendered_views, write_views

pytest.importorskip("cv2")
from sofia_calibrator.targets.charuco import BoardNotFound, BoardSpec, board_poses, render_view

K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])


def _views(n: int, seed: int):  # type: ignore[no-untyped-def]
    """(X true T_flange_cam, T_base_flange (n, 4, 4), true T_cam_board (n, 4, 4), images)."""
    return rendered_views(
        n, seed, lambda b: render_view(b, K, (640, 480)), (0.4, 0.6), np.r_[0.14, 0.10, 0.0]
    )


def test_rendered_charuco_views_calibrate() -> None:
    X, A, B, images = _views(8, 30)
    measured = board_poses(images, K, BoardSpec())
    assert np.abs(measured[:, :3, 3] - B[:, :3, 3]).max() < 3e-3
    fit = hand_eye_from_poses(A, measured)
    ours = np.linalg.norm(error6(fit.X, X)[:3])
    best = min(np.linalg.norm(error6(Xb, X)[:3]) for Xb in fit.baselines.values())
    assert ours < 3e-3 and ours <= 1.1 * best, (ours, best)
    cal = calibrate_target("charuco", T_base_flange=A, images=images, K=K)
    np.testing.assert_allclose(cal.T_flange_cam, fit.X, atol=1e-6)


def test_a_view_without_the_board_is_named() -> None:
    _, A, _, images = _views(4, 31)
    images[2] = np.full_like(images[2], 255)
    with pytest.raises(BoardNotFound, match="view 2: 0 ChArUco corners"):
        calibrate_target("charuco", T_base_flange=A, images=images, K=K)


def test_the_command_calibrates_a_charuco_board(tmp_path: Path) -> None:
    X, A, _, images = _views(8, 32)
    names, poses = write_views(tmp_path, images, A)
    base = [SOFIA, "calibrate", "--target", "charuco", "--euler-poses", str(poses),
            "--camera-matrix", "600 600 320 240"]  # fmt: skip
    out = subprocess.run([*base, "--images", *names, "--board", "7", "5", "0.04", "0.03", "--json"],
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    msg = json.loads(out.stdout)
    assert msg["parent_frame"] == "panda_link8" and "pose target" in msg["correction_reason"]
    assert np.linalg.norm(np.array(msg["translation"]) - X[:3, 3]) < 3e-3
    # the same result as the Python call on the same views
    cal = calibrate_target("charuco", T_base_flange=A, images=images, K=K)
    np.testing.assert_allclose(np.array(msg["matrix"]), cal.T_flange_cam, atol=1e-5)
    bad = subprocess.run([*base, "--images", *names[:3]], capture_output=True, text=True, timeout=120)
    assert bad.returncode != 0 and "3 images but 8 flange poses" in bad.stderr
    bad = subprocess.run([*base, "--images", *names, "--board-dict", "DICT_9X9"], capture_output=True, text=True,
                         timeout=120)  # fmt: skip
    assert bad.returncode != 0 and "not an OpenCV ArUco dictionary" in bad.stderr


def _clouds(B: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    """Organized (480, 640, 3) clouds of the board planes T_cam_board B (n, 4, 4) through K, with the
    D435 model's depth noise (camera frame, metres)."""
    from sofia_calibrator.fitting.noise import camera_sigma

    v, u = np.mgrid[0:480, 0:640]
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(u.shape)], axis=-1)
    out = []
    for b in B:
        p = rays * ((b[:3, 2] @ b[:3, 3]) / (rays @ b[:3, 2]))[..., None]
        p[..., 2] += rng.standard_normal(u.shape) * camera_sigma(p.reshape(-1, 3))[:, 2].reshape(u.shape)
        out.append(p)
    return out


def test_corners_with_depth_beat_the_board_poses_alone() -> None:
    rng = np.random.default_rng(5)
    poses, points, sigma = [], [], []
    for seed in range(4):
        X, A, B, images = _views(8, 50 + seed)
        by_pose = calibrate_target("charuco", T_base_flange=A, images=images, K=K)
        cal = calibrate_target("charuco", T_base_flange=A, images=images, K=K, clouds_cam=_clouds(B, rng))
        poses.append(np.linalg.norm(error6(by_pose.T_flange_cam, X)[:3]))
        points.append(np.linalg.norm(error6(cal.T_flange_cam, X)[:3]))
        sigma.append(cal.std_translation_mm)
        assert "then the corners with depth" in cal.correction_reason
    rms = [1e3 * float(np.sqrt(np.mean(np.square(e)))) for e in (poses, points)]
    assert rms[1] < 0.8 * rms[0] and rms[1] < 1.0, rms  # 8 views at 0.4-0.6 m
    assert 0.02 < np.mean(sigma) < 1.0, sigma  # a 1-sigma of the corners' scale, not of the poses'


def test_the_command_takes_the_corners_depth_from_depth_images(tmp_path: Path) -> None:
    """``--depth``: one 16-bit depth image per view (here 0.1 mm units), back-projected through the
    camera matrix; the result is the Python call's on the same clouds, nearer the truth than the
    board poses alone."""
    import cv2
    from sofia_calibrator.targets.files import read_depth_clouds

    X, A, B, images = _views(8, 60)
    names, poses = write_views(tmp_path, images, A)
    depth_names = []
    for i, cloud in enumerate(_clouds(B, np.random.default_rng(6))):
        depth_names.append(str(tmp_path / f"depth{i}.png"))
        cv2.imwrite(depth_names[-1], np.nan_to_num(np.round(cloud[..., 2] / 1e-4)).astype(np.uint16))
    base = [SOFIA, "calibrate", "--target", "charuco", "--euler-poses", str(poses), "--camera-matrix",
            "600 600 320 240", "--images", *names]  # fmt: skip
    out = subprocess.run([*base, "--depth", *depth_names, "--depth-unit", "0.0001", "--json"],
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    msg = json.loads(out.stdout)
    assert "then the corners with depth" in msg["correction_reason"]
    clouds = read_depth_clouds(depth_names, K, 1e-4)
    cal = calibrate_target("charuco", T_base_flange=A, images=images, K=K, clouds_cam=clouds)
    np.testing.assert_allclose(np.array(msg["matrix"]), cal.T_flange_cam, atol=1e-5)
    by_pose = calibrate_target("charuco", T_base_flange=A, images=images, K=K)
    err_depth = np.linalg.norm(error6(cal.T_flange_cam, X)[:3])
    assert err_depth < 1e-3 and err_depth < np.linalg.norm(error6(by_pose.T_flange_cam, X)[:3])
    bad = subprocess.run([*base, "--depth", *depth_names[:2]], capture_output=True, text=True, timeout=120)
    assert bad.returncode != 0 and "2 depth images but 8 images" in bad.stderr
