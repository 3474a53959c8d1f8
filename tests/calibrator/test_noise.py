"""Noise learned from the data: the isotropic component, the warning, calibrated coverage under noise
the solver does not assume, the 6x6 covariance."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_calibrator import calibrate
from sofia_calibrator.eye_to_hand import SETUPS, calibrate_eye_to_hand
from sofia_calibrator.fitting.diagnostics import error6
from sofia_calibrator.fitting.noise import camera_sigma, isotropic_component
from sofia_calibrator.fitting.simulate import (
    UNMODELLED_NOISE,
    make_eye_to_hand,
    make_problem,
    unmodelled_eye_to_hand,
    unmodelled_problem,
)

CHI2_6_68 = 7.0406


def test_isotropic_component_recovers_a_known_level() -> None:
    rng = np.random.default_rng(0)
    p = np.c_[rng.uniform(-0.1, 0.1, (4000, 2)), rng.uniform(0.3, 0.7, 4000)]
    cam = camera_sigma(p)
    errors = rng.standard_normal(p.shape) * np.sqrt(cam**2 + 0.002**2)
    assert isotropic_component(errors, cam, errors.size) == pytest.approx(0.002, rel=0.03)
    assert isotropic_component(0.5 * cam, cam, errors.size) == 0.0  # the camera alone explains it
    assert np.isnan(isotropic_component(errors, cam, 0))


@pytest.mark.parametrize("robot_mm", [1.0, 3.0])
def test_noise_mm_is_estimated_and_far_above_the_camera_warns(robot_mm: float) -> None:
    rng = np.random.default_rng(int(robot_mm))
    est = []
    for _ in range(30):
        pr = make_problem(20, rng, robot_noise_m=robot_mm * 1e-3)
        cal = calibrate(pr.p_cam, pr.T_base_flange)
        est.append(cal.noise_mm)
        true_mm = 1e3 * np.sqrt(np.mean(pr.sigma**2))
        warned = any("what the camera explains" in w for w in cal.warnings)
        assert warned == (cal.noise_scale > 3.0)
    assert np.median(est) == pytest.approx(true_mm, rel=0.2)
    if robot_mm == 3.0:
        assert cal.noise_scale > 3.0 and warned


def test_camera_noise_alone_does_not_warn() -> None:
    pr = make_problem(15, np.random.default_rng(3))
    cal = calibrate(pr.p_cam, pr.T_base_flange)
    assert not any("camera explains" in w for w in cal.warnings)
    assert cal.noise_scale < 3.0


def test_covariance_is_6x6_and_matches_the_reported_sigmas() -> None:
    pr = make_problem(12, np.random.default_rng(4), robot_noise_m=0.002)
    cal = calibrate(pr.p_cam, pr.T_base_flange)
    C = cal.covariance6
    assert C.shape == (6, 6) and np.allclose(C, C.T) and np.all(np.linalg.eigvalsh(C) > 0)
    np.testing.assert_allclose(1e3 * np.sqrt(np.diag(C)[:3]), cal.std_translation_mm, rtol=1e-9)
    np.testing.assert_allclose(np.degrees(np.sqrt(np.diag(C)[3:])), cal.std_rotation_deg, rtol=1e-9)


@pytest.mark.parametrize("rotation_noise_deg", [0.0, 0.05])
def test_coverage_under_noise_the_solver_does_not_assume(rotation_noise_deg: float) -> None:
    """Robot pose noise 1-3 mm (and a small rotation error), the camera's own noise, half the sets
    with a 3-5 % depth error: the reported 1-sigma, 2-sigma and 6-DoF region cover as they say."""
    rng = np.random.default_rng(10 + int(100 * rotation_noise_deg))
    in1, in2, maha = [], [], []
    for k in range(300):
        pr = make_problem(
            int(rng.integers(6, 21)), rng, robot_noise_m=float(rng.uniform(0.001, 0.003)),
            robot_noise_deg=rotation_noise_deg, depth_scale=float(rng.uniform(0.95, 0.97)) if k % 2 else 1.0,
        )  # fmt: skip
        cal = calibrate(pr.p_cam, pr.T_base_flange, leave_one_out=False)
        e = error6(cal.T_flange_cam, pr.T_flange_cam)
        sd = np.sqrt(np.diag(cal.covariance6))
        in1.append(np.abs(e) <= sd)
        in2.append(np.abs(e) <= 2 * sd)
        maha.append(e @ np.linalg.solve(cal.covariance6, e) <= CHI2_6_68)
    # targets 62-74 %, 92-98 %, 60-76 %, widened by the Monte Carlo error of 300 sets
    assert 0.60 <= np.mean(in1) <= 0.77, np.mean(in1, axis=0)
    assert 0.90 <= np.mean(in2) <= 0.985, np.mean(in2, axis=0)
    assert 0.56 <= np.mean(maha) <= 0.80, np.mean(maha)


SETS_PER_N = 400  # per sample count n = 6, 11, 20, 50: 1600 sets, 4800 axis-trials per set-up and noise


def _coverage(setup: str, kind: str, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, bool]:
    """(3,) translation error over its 1-sigma, (3,) the same over 2-sigma, and whether a
    sample was flagged, for one set of ``kind`` noise in ``setup``."""
    if setup == "eye-to-hand":
        eth = unmodelled_eye_to_hand(kind, n, rng)
        cal = calibrate_eye_to_hand(
            eth.p_cam, eth.T_base_flange, leave_one_out=False, enforce_criterion=False
        )
        truth = eth.T_base_cam
    else:
        eih = unmodelled_problem(kind, n, rng)
        cal = calibrate(eih.p_cam, eih.T_base_flange, leave_one_out=False, enforce_criterion=False)
        truth = eih.T_flange_cam
    e = np.abs(error6(cal.T_flange_cam, truth)[:3])
    sd = np.sqrt(np.diag(cal.covariance6))[:3]
    return e <= sd, e <= 2 * sd, bool(cal.outliers)


@pytest.mark.parametrize("setup", SETUPS)
@pytest.mark.parametrize("kind", UNMODELLED_NOISE)
def test_translation_coverage_and_false_alarms_under_noise_the_solver_does_not_assume(
    setup: str, kind: str
) -> None:
    """Student-t, correlated robot error, depth noise 3x the model, depth scale 0.95, at n = 6, 11,
    20, 50, eye-in-hand and eye-to-hand: over the four n, translation within 1-sigma 62-74 % and
    within 2-sigma 92-98 % (the targets themselves: with 4800 axis-trials the Monte Carlo 1-sigma
    is about 0.7 and 0.3 points), a false outlier in <= 2 % of sets; each n within the targets
    widened by about three Monte Carlo sigmas of its 1200 axis-trials (4 and 2.5 points). Seeds:
    numpy ``default_rng([36, n, kind index, set-up index])``."""
    in1, in2, flagged = {}, {}, 0
    for n in (6, 11, 20, 50):
        rng = np.random.default_rng([36, n, UNMODELLED_NOISE.index(kind), SETUPS.index(setup)])
        a1, a2 = [], []
        for _ in range(SETS_PER_N):
            c1, c2, f = _coverage(setup, kind, n, rng)
            a1.append(c1)
            a2.append(c2)
            flagged += f
        in1[n], in2[n] = float(np.mean(a1)), float(np.mean(a2))
    pooled1, pooled2 = np.mean(list(in1.values())), np.mean(list(in2.values()))
    assert 0.62 <= pooled1 <= 0.74 and all(0.58 <= v <= 0.78 for v in in1.values()), in1
    # eye-to-hand with a 0.95 depth scale at n = 6: one set in six shows no sign of the scale
    # (likelihood ratio < 3), and those carry its 40 mm shift uncovered: 88-90 % within 2-sigma
    low2 = 0.87 if (setup, kind) == ("eye-to-hand", "scale") else 0.895
    assert 0.92 <= pooled2 <= 0.98 and all(low2 <= v <= 0.995 for v in in2.values()), in2
    assert flagged <= 0.02 * 4 * SETS_PER_N, flagged


def test_eye_to_hand_coverage_with_half_the_cameras_reading_depth_4_percent_long() -> None:
    """A fixed camera 0.6-0.9 m away, a target on the flange, 12 poses, 1 mm robot noise, every
    other set's depth 4 % long (a scale the test often cannot see from so little depth range):
    translation within 1-sigma 62-74 %, within 2-sigma 92-98 % (800 sets, 2400 axis-trials: Monte
    Carlo 1-sigma about 1 and 0.5 points; measured 66-68 % and 93-95 % with seeds 36-38)."""
    rng = np.random.default_rng(36)
    in1, in2 = [], []
    for k in range(800):
        pr = make_eye_to_hand(12, rng, robot_noise_m=0.001, depth_scale=0.96 if k % 2 else 1.0)
        cal = calibrate_eye_to_hand(pr.p_cam, pr.T_base_flange, leave_one_out=False, enforce_criterion=False)
        e = np.abs(error6(cal.T_flange_cam, pr.T_base_cam)[:3])
        sd = np.sqrt(np.diag(cal.covariance6))[:3]
        in1.append(e <= sd)
        in2.append(e <= 2 * sd)
    assert 0.62 <= np.mean(in1) <= 0.74, np.mean(in1, axis=0)
    assert 0.92 <= np.mean(in2) <= 0.98, np.mean(in2, axis=0)
