"""AprilTag target: rendered views detected by OpenCV's aruco AprilTag dictionaries, the tag poses
recovered, the hand-eye transform as accurate as OpenCV's best method on the same views, from
Python and from the command; a view without the tag says which."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator.any_target import calibrate_target
from sofia_calibrator.errors import InputMismatch
from sofia_calibrator.fitting.diagnostics import error6
from sofia_calibrator.targets.apriltag import TagNotFound, TagSpec, render_tag_view, tag_poses
from sofia_calibrator.targets.poses import hand_eye_from_poses

from ..conftest import SOFIA
from .conftest import rendered_views, write_views

cv2 = pytest.importorskip("cv2")

K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])
TAG = TagSpec(side_m=0.1, tag_id=7)


def _views(n: int, seed: int):  # type: ignore[no-untyped-def]
    """(X true T_flange_cam, T_base_flange (n, 4, 4), true T_cam_tag (n, 4, 4), images)."""
    return rendered_views(n, seed, lambda b: render_tag_view(b, K, (640, 480), TAG), (0.35, 0.5))


def test_rendered_apriltag_views_calibrate() -> None:
    X, A, B, images = _views(10, 40)
    measured = tag_poses(images, K, TAG)
    assert np.abs(measured[:, :3, 3] - B[:, :3, 3]).max() < 3e-3
    fit = hand_eye_from_poses(A, measured, TAG.side_m)
    ours = np.linalg.norm(error6(fit.X, X)[:3])
    best = min(np.linalg.norm(error6(Xb, X)[:3]) for Xb in fit.baselines.values())
    assert ours < 5e-3 and ours <= 1.1 * best, (ours, best)
    cal = calibrate_target("apriltag", T_base_flange=A, images=images, K=K, tag=TAG)
    np.testing.assert_allclose(cal.T_flange_cam, fit.X, atol=1e-6)


def test_a_view_without_the_tag_and_a_bad_family_are_named() -> None:
    _, A, _, images = _views(4, 41)
    images[1] = np.full_like(images[1], 255)
    with pytest.raises(TagNotFound, match="view 1: tag 7 of DICT_APRILTAG_36h11 not found"):
        calibrate_target("apriltag", T_base_flange=A, images=images, K=K, tag=TAG)
    with pytest.raises(InputMismatch, match="not one of OpenCV's DICT_APRILTAG"):
        tag_poses(images, K, TagSpec(family="DICT_4X4_50"))


def test_the_command_calibrates_an_apriltag(tmp_path: Path) -> None:
    X, A, _, images = _views(8, 42)
    names, poses = write_views(tmp_path, images, A)
    out = subprocess.run(
        [SOFIA, "calibrate", "--target", "apriltag", "--images", *names, "--camera-matrix", "600 600 320 240",
         "--tag-size", "0.1", "--tag-id", "7", "--euler-poses", str(poses), "--json"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    msg = json.loads(out.stdout)
    assert msg["parent_frame"] == "panda_link8" and "pose target" in msg["correction_reason"]
    assert np.linalg.norm(np.array(msg["translation"]) - X[:3, 3]) < 5e-3
