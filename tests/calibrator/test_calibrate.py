"""calibrate(): real lab data, outliers, diagnostics, observability and malformed inputs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_calibrator import (
    CalibrationError,
    DegenerateMotion,
    InputMismatch,
    TooFewSamples,
    calibrate,
    dissipation,
    map_to_base,
    read_lab,
    spread,
)
from sofia_calibrator.fitting.simulate import make_problem


def test_lab_data_default_models_the_depth_scale_and_keeps_every_sample(lab_dir: Path) -> None:
    p_cam, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    assert len(p_cam) == 11
    cal = calibrate(p_cam, T)
    # every sample kept, the depth (z) reads about 5 % long, the lab's criterion met
    assert cal.inliers == list(range(11)) and cal.outliers == [] and cal.with_all_samples is None
    assert cal.correction.model == "depth_scale"
    assert 0.94 <= cal.correction.depth_scale <= 0.96
    assert cal.correction.depth_scale_sigma is not None and 0.002 < cal.correction.depth_scale_sigma < 0.02
    assert cal.passes and np.all(cal.spread_mm < 10.0)
    # leave-one-out blob prediction RMS (the plain rigid fit: above 4 mm)
    assert float(np.sqrt(np.mean(cal.leave_one_out_mm**2))) <= 2.4
    # why: the F-test against the rigid model, and AIC, for every candidate
    by_model = {c.model: c for c in cal.candidates}
    assert set(by_model) == {"rigid", "depth_scale"}  # ray_scale only when asked
    assert by_model["depth_scale"].p_value is not None and by_model["depth_scale"].p_value < 1e-6
    assert by_model["depth_scale"].aic < by_model["rigid"].aic - 20
    assert "F-test" in cal.correction_reason and "AIC" in cal.correction_reason
    # the reported spread is the lab's criterion through the full model, recomputed independently
    corrected = p_cam * np.r_[1.0, 1.0, cal.correction.depth_scale]
    mapped = map_to_base(T, cal.T_flange_cam, corrected)
    np.testing.assert_allclose(cal.map_to_base(p_cam, T), mapped, atol=1e-12)
    np.testing.assert_allclose(cal.spread_mm, 1e3 * spread(mapped), rtol=1e-9)
    np.testing.assert_allclose(cal.dissipation_after, dissipation(mapped), rtol=1e-9)
    # a camera about 12 cm from the flange
    assert 0.05 < np.linalg.norm(cal.translation) < 0.2
    assert np.all(cal.std_translation_mm < 10.0) and np.all(cal.std_rotation_deg < 2.0)
    assert not any("outlier" in w or "criterion" in w for w in cal.warnings)


def test_lab_data_rigid_fails_the_criterion_and_only_advises(lab_dir: Path) -> None:
    p_cam, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    cal = calibrate(p_cam, T, correction="rigid")
    assert cal.correction.model == "rigid" and cal.correction.depth_scale == 1.0
    assert not cal.passes and cal.spread_mm.max() > 10.0
    # nothing removed: the removal that would meet the criterion is advice
    assert cal.inliers == list(range(11)) and cal.outliers == []
    assert cal.criterion_advice == [0]
    assert any("removing samples [0] would meet it" in w and "nothing was removed" in w for w in cal.warnings)
    assert float(np.sqrt(np.mean(cal.leave_one_out_mm**2))) > 4.0
    assert int(np.argmax(cal.leave_one_out_mm)) == 0


def test_lab_leave_one_out_from_the_hat_matrix_matches_refits(lab_dir: Path) -> None:
    p_cam, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    for correction in ("rigid", "depth_scale"):
        cal = calibrate(p_cam, T, correction=correction)
        exact = []
        for i in range(11):
            keep = np.delete(np.arange(11), i)
            other = calibrate(p_cam[keep], T[keep], correction=correction, sigma=cal.sigma[keep])
            exact.append(
                1e3 * np.linalg.norm(other.map_to_base(p_cam[i : i + 1], T[i : i + 1])[0] - other.p_base)
            )
        np.testing.assert_allclose(cal.leave_one_out_mm, exact, rtol=0.1, atol=0.1)


def test_lab_plain_fit_agrees_with_scipy_least_squares(lab_dir: Path) -> None:
    """The optimum of our LM is the optimum scipy's least_squares finds on the same residuals."""
    from scipy.optimize import least_squares

    p_cam, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    for correction in ("rigid", "depth_scale"):
        cal = calibrate(p_cam, T, sigma="uniform", exclude_outliers=False, correction=correction)

        def residuals(x: np.ndarray, correction: str = correction) -> np.ndarray:
            T_fc = np.eye(4)
            T_fc[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix()
            T_fc[:3, 3] = x[3:6]
            p = p_cam * np.r_[1.0, 1.0, x[9]] if correction == "depth_scale" else p_cam
            return (map_to_base(T, T_fc, p) - x[6:9]).ravel()

        x0 = np.r_[
            Rotation.from_matrix(cal.T_flange_cam[:3, :3]).as_rotvec() + 0.05, cal.translation + 0.01,
            cal.p_base, 1.0,
        ]  # fmt: skip
        ref = least_squares(residuals, x0, xtol=1e-14, ftol=1e-14, gtol=1e-14)
        np.testing.assert_allclose(cal.translation, ref.x[3:6], atol=1e-6)
        if correction == "depth_scale":
            np.testing.assert_allclose(cal.correction.depth_scale, ref.x[9], atol=1e-6)


def test_clear_outlier_is_found_by_robust_statistics() -> None:
    pr = make_problem(16, np.random.default_rng(11))
    p_cam = pr.p_cam.copy()
    p_cam[7] += [0.0, 0.02, 0.03]
    cal = calibrate(p_cam, pr.T_base_flange)
    assert cal.outliers == [7]
    assert cal.with_all_samples is not None
    assert np.linalg.norm(cal.translation - pr.T_flange_cam[:3, 3]) < 0.005
    assert any("clear outlier by the leave-one-out test" in w for w in cal.warnings)


def test_clean_data_has_no_outliers_and_passes() -> None:
    pr = make_problem(12, np.random.default_rng(2))
    cal = calibrate(pr.p_cam, pr.T_base_flange)
    assert cal.outliers == [] and cal.passes and cal.warnings == []
    assert cal.with_all_samples is None
    assert np.all(cal.residuals_mm < 5.0)


def _rot_about(axis: str, angles_deg: np.ndarray) -> np.ndarray:
    return Rotation.from_euler(axis, angles_deg[:, None], degrees=True).as_matrix()


def test_translation_only_motion_is_refused_with_advice() -> None:
    pr = make_problem(8, np.random.default_rng(4))
    T = pr.T_base_flange.copy()
    T[:, :3, :3] = T[0, :3, :3]
    with pytest.raises(DegenerateMotion, match="translation-only"):
        calibrate(pr.p_cam, T)


def test_rotation_about_one_axis_only_is_refused_with_advice() -> None:
    pr = make_problem(8, np.random.default_rng(4))
    T = pr.T_base_flange.copy()
    T[:, :3, :3] = _rot_about("z", np.linspace(-40, 40, 8)) @ T[0, :3, :3]
    with pytest.raises(DegenerateMotion, match=r"one axis.*another axis"):
        calibrate(pr.p_cam, T)


def test_too_few_samples() -> None:
    pr = make_problem(4, np.random.default_rng(0))
    with pytest.raises(TooFewSamples, match="2 calibration sample"):
        calibrate(pr.p_cam[:2], pr.T_base_flange[:2])


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (
            lambda p, T: (np.where(np.arange(18).reshape(6, 3) == 4, np.nan, p), T),
            r"p_cam has non-finite values in rows \[1\]",
        ),
        (lambda p, T: (p[:5], T), "5 blob positions .* but 6 flange poses"),
        (lambda p, T: (p, T * np.r_[1.0, 1.0, 1.0, 1.0][None, None, :] * 1.1), "not a rotation"),
        (lambda p, T: (p[:, :2], T), r"shape \(n, 3\)"),
        (lambda p, T: (p * np.r_[1, 1, -1], T), "z <= 0"),
        (lambda p, T: (p, T[:, :3, :]), r"shape \(4, 4\)"),
    ],
)
def test_malformed_inputs_are_clear_errors(mutate, match) -> None:  # type: ignore[no-untyped-def]
    pr = make_problem(6, np.random.default_rng(1))
    p, T = mutate(pr.p_cam, pr.T_base_flange)
    with pytest.raises(ValueError, match=match):
        calibrate(p, T)


def test_bad_guess_and_options_are_clear_errors() -> None:
    pr = make_problem(6, np.random.default_rng(1))
    with pytest.raises(ValueError, match=r"guess .* not a rotation"):
        calibrate(pr.p_cam, pr.T_base_flange, guess=np.diag([1.0, 2.0, 1.0, 1.0]))
    with pytest.raises(InputMismatch, match="loss must be one of"):
        calibrate(pr.p_cam, pr.T_base_flange, loss="l1")
    with pytest.raises(CalibrationError, match="sigma must be finite and positive"):
        calibrate(pr.p_cam, pr.T_base_flange, sigma=np.zeros(6))
