"""Eye-to-hand: a fixed camera and a flange-mounted target, recovered from no guess with an honest
uncertainty; its result names the base and camera frames; the set-up is validated."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_calibrator import to_message, to_yaml
from sofia_calibrator.errors import InputMismatch
from sofia_calibrator.eye_to_hand import calibrate_eye_to_hand, calibrate_setup
from sofia_calibrator.fitting.diagnostics import error6
from sofia_calibrator.fitting.simulate import make_eye_to_hand


def test_a_fixed_camera_and_the_target_on_the_flange_are_recovered() -> None:
    rng = np.random.default_rng(5)
    inside, scaled = [], 0
    for k in range(60):
        ds = 0.96 if k % 2 else 1.0
        pr = make_eye_to_hand(14, rng, robot_noise_m=0.001, depth_scale=ds)
        cal = calibrate_eye_to_hand(pr.p_cam, pr.T_base_flange, leave_one_out=False)
        e = error6(cal.T_flange_cam, pr.T_base_cam)
        assert np.linalg.norm(e[:3]) < 0.05 and np.degrees(np.linalg.norm(e[3:])) < 2.0
        assert np.linalg.norm(cal.p_base - pr.p_flange) < 0.01  # the target, flange frame
        inside.append(np.abs(e[:3]) <= np.sqrt(np.diag(cal.covariance6))[:3])
        scaled += (cal.correction.model == "depth_scale") == (ds != 1.0)
    assert 0.58 <= np.mean(inside) <= 0.80, np.mean(inside)
    assert scaled >= 50


def test_noise_free_eye_to_hand_is_exact_and_names_the_base_and_camera_frames() -> None:
    pr = make_eye_to_hand(8, np.random.default_rng(6), noise_scale=0.0)
    cal = calibrate_setup(pr.p_cam, pr.T_base_flange, "eye-to-hand", correction="rigid")
    np.testing.assert_allclose(cal.T_flange_cam, pr.T_base_cam, atol=1e-7)
    np.testing.assert_allclose(cal.p_base, pr.p_flange, atol=1e-7)
    msg = to_message(cal)
    assert msg.parent_frame == "panda_link0" and msg.child_frame == "camera_link_optical"
    assert "panda_link0" in to_yaml(msg)


def test_the_setup_is_validated() -> None:
    pr = make_eye_to_hand(8, np.random.default_rng(7))
    with pytest.raises(InputMismatch, match="setup must be one of"):
        calibrate_setup(pr.p_cam, pr.T_base_flange, "eye-on-head")
    with pytest.raises(ValueError, match="T_base_flange"):
        calibrate_eye_to_hand(pr.p_cam, pr.T_base_flange[:, :3, :])
