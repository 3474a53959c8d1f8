"""Outliers only when they are outliers, the lab criterion as advice, robust starts (5 samples, a
guess 90 degrees off), observability advice."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_calibrator import DegenerateMotion, calibrate, read_lab
from sofia_calibrator.fitting.noise import camera_sigma
from sofia_calibrator.fitting.simulate import make_problem


def test_clean_sets_rarely_have_a_false_outlier() -> None:
    """Robot noise 1-3 mm plus the camera's (not the model the solver assumes): <= 1 % of sets."""
    rng = np.random.default_rng(21)
    flagged = 0
    for _ in range(300):
        pr = make_problem(int(rng.integers(8, 31)), rng, robot_noise_m=float(rng.uniform(0.001, 0.003)))
        flagged += bool(calibrate(pr.p_cam, pr.T_base_flange, leave_one_out=False).outliers)
    assert flagged <= 3


def test_the_lab_criterion_never_removes_samples_it_advises() -> None:
    pr = make_problem(12, np.random.default_rng(8), robot_noise_m=0.002)
    p_cam = pr.p_cam.copy()
    p_cam[3] += [0.0, 0.0, 0.012]  # one sample 12 mm off: the spread fails
    cal = calibrate(p_cam, pr.T_base_flange)
    assert not cal.passes
    assert cal.inliers == list(range(12)) and cal.outliers == []
    assert cal.criterion_advice, cal.warnings
    keep = [i for i in range(12) if i not in cal.criterion_advice]
    assert calibrate(p_cam[keep], pr.T_base_flange[keep]).passes
    assert any("advice only: nothing was removed" in w for w in cal.warnings)


def test_five_sample_subsets_of_the_lab_land_near_the_full_answer(lab_dir: Path) -> None:
    p, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    full = calibrate(p, T)
    subsets = list(itertools.combinations(range(11), 5))
    rng = np.random.default_rng(0)
    for k in rng.choice(len(subsets), 40, replace=False):
        s = list(subsets[k])
        cal = calibrate(p[s], T[s])
        assert np.linalg.norm(cal.translation - full.translation) < 0.08, (s, cal.translation)
        assert any("poses" in w for w in cal.warnings)  # few poses: add poses


@pytest.mark.parametrize("n", [4, 5])
def test_four_and_five_sample_sets_are_solved_from_no_guess(n: int) -> None:
    for seed in range(15):
        pr = make_problem(n, np.random.default_rng(100 + seed), noise_scale=0.5)
        cal = calibrate(pr.p_cam, pr.T_base_flange)
        assert np.linalg.norm(cal.translation - pr.T_flange_cam[:3, 3]) < 0.03, seed


def test_a_guess_90_degrees_off_is_one_more_start() -> None:
    rng = np.random.default_rng(7)
    for _ in range(40):
        pr = make_problem(int(rng.integers(6, 15)), rng, robot_noise_m=0.001)
        guess = pr.T_flange_cam.copy()
        axis = rng.normal(size=3)
        guess[:3, :3] = (
            Rotation.from_rotvec(np.pi / 2 * axis / np.linalg.norm(axis)).as_matrix() @ guess[:3, :3]
        )
        a = calibrate(pr.p_cam, pr.T_base_flange, guess=guess)
        b = calibrate(pr.p_cam, pr.T_base_flange)
        np.testing.assert_allclose(a.T_flange_cam, b.T_flange_cam, atol=1e-6)
        # the plot's "before" is the guess, not the closed-form start
        before = np.einsum(
            "nij,nj->ni", pr.T_base_flange[:, :3, :3], pr.p_cam @ guess[:3, :3].T + guess[:3, 3]
        )
        np.testing.assert_allclose(a.mapped_start, before + pr.T_base_flange[:, :3, 3], atol=1e-12)


def test_without_a_guess_before_is_the_identity() -> None:
    pr = make_problem(8, np.random.default_rng(2))
    cal = calibrate(pr.p_cam, pr.T_base_flange)
    expected = np.einsum("nij,nj->ni", pr.T_base_flange[:, :3, :3], pr.p_cam) + pr.T_base_flange[:, :3, 3]
    np.testing.assert_allclose(cal.mapped_start, expected, atol=1e-12)


def test_small_rotations_about_every_axis_are_not_called_one_axis() -> None:
    pr = make_problem(10, np.random.default_rng(4))
    T = pr.T_base_flange.copy()
    small = Rotation.from_rotvec(np.radians(1.0) * np.random.default_rng(1).normal(size=(10, 3))).as_matrix()
    T[:, :3, :3] = T[0, :3, :3] @ small
    with pytest.raises(DegenerateMotion) as e:
        calibrate(pr.p_cam, T)
    assert "one axis" not in str(e.value)
    assert "barely rotates" in str(e.value) or "small about every axis" in str(e.value)


def test_sets_resting_on_few_orientations_get_add_poses_advice() -> None:
    pr = make_problem(4, np.random.default_rng(6), robot_noise_m=0.001)
    cal = calibrate(pr.p_cam, pr.T_base_flange)
    advice = [w for w in cal.warnings if "add poses" in w]
    assert advice and "mm" in advice[0] and "with 4 more" in advice[0], cal.warnings
    # ten poses but only three flange orientations (the camera moved without turning)
    rng = np.random.default_rng(6)
    pr = make_problem(3, rng)
    T_base_cam = np.repeat(pr.T_base_flange @ pr.T_flange_cam, [4, 3, 3], axis=0)
    T_base_cam[:, :3, 3] += rng.uniform(-0.05, 0.05, (10, 3))
    p_cam = np.einsum("nji,nj->ni", T_base_cam[:, :3, :3], pr.p_base - T_base_cam[:, :3, 3])
    T = T_base_cam @ np.linalg.inv(pr.T_flange_cam)
    cal = calibrate(p_cam + rng.normal(0, 5e-4, p_cam.shape), T)
    advice = [w for w in cal.warnings if "3 distinct flange orientations" in w]
    assert advice and "with 4 more" in advice[0], cal.warnings


@pytest.mark.parametrize("sigma", ["depth", "array"])
@pytest.mark.parametrize(("n", "n_bad"), [(100, 10), (200, 12), (300, 20)])
def test_many_outliers_are_all_excluded(sigma: str, n: int, n_bad: int) -> None:
    """About 5 % of the samples from other cameras (hundreds of mm off): each removal refits, and
    each round's test must use the influence of the current fit (a stale one named indices beyond
    the kept samples: IndexError, or silently removed the wrong sample)."""
    good = make_problem(n, np.random.default_rng(3))
    bad = [make_problem(1, np.random.default_rng(seed)) for seed in range(100, 100 + n_bad)]
    p_cam = np.concatenate([good.p_cam, *(b.p_cam for b in bad)])
    T = np.concatenate([good.T_base_flange, *(b.T_base_flange for b in bad)])
    cal = calibrate(p_cam, T, sigma=camera_sigma(p_cam) if sigma == "array" else "depth", leave_one_out=False)
    assert sorted(cal.outliers) == list(range(n, n + n_bad))
    assert cal.inliers == list(range(n)) and cal.passes
    kept = calibrate(p_cam, T, exclude_outliers=False, sigma="depth")
    assert sorted(kept.outliers) == list(range(n, n + n_bad)) and kept.inliers == list(range(n + n_bad))
    assert kept.without_outliers is not None and len(kept.leave_one_out_mm) == n + n_bad
