"""The solver recovers a known T_flange_cam from no guess; hypothesis generates the problems."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from sofia_calibrator import calibrate, solve
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.fitting.so3 import exp, hat, project

from ..conftest import gap_mm_deg


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(6, 30))
def test_recovers_known_transform_from_no_guess(seed: int, n: int) -> None:
    pr = make_problem(n, np.random.default_rng(seed))
    sol = solve(pr.p_cam, pr.T_base_flange, pr.sigma)
    dt, dr = gap_mm_deg(sol.T_flange_cam, pr.T_flange_cam)
    assert dt < 15.0 and dr < 2.0, (dt, dr)
    # the optimum from no guess is the one reached from the truth
    from_truth = solve(pr.p_cam, pr.T_base_flange, pr.sigma, T_flange_cam_guess=pr.T_flange_cam)
    assert abs(sol.cost - from_truth.cost) <= 1e-6 * max(from_truth.cost, 1.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(4, 12))
def test_noise_free_is_exact(seed: int, n: int) -> None:
    pr = make_problem(n, np.random.default_rng(seed), noise_scale=0.0)
    sol = solve(pr.p_cam, pr.T_base_flange)
    np.testing.assert_allclose(sol.T_flange_cam, pr.T_flange_cam, atol=1e-6)
    np.testing.assert_allclose(sol.p_base, pr.p_base, atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(phi=st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3))
def test_exp_is_a_rotation_and_hat_is_cross(phi: list[float]) -> None:
    v = np.array(phi)
    R = exp(v)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(R, Rotation.from_rotvec(v).as_matrix(), atol=1e-10)
    w = np.array([0.3, -1.0, 2.0])
    np.testing.assert_allclose(hat(v) @ w, np.cross(v, w), atol=1e-12)
    np.testing.assert_allclose(project(R + 1e-9), R, atol=1e-7)


def test_guess_is_accepted_and_reaches_the_same_optimum() -> None:
    pr = make_problem(11, np.random.default_rng(3))
    guess = pr.T_flange_cam.copy()
    guess[:3, :3] = guess[:3, :3] @ Rotation.from_euler("xyz", [10, -8, 12], degrees=True).as_matrix()
    guess[:3, 3] += [0.02, -0.02, 0.01]
    a = calibrate(pr.p_cam, pr.T_base_flange, guess=guess, sigma=pr.sigma)
    b = calibrate(pr.p_cam, pr.T_base_flange, sigma=pr.sigma)
    np.testing.assert_allclose(a.T_flange_cam, b.T_flange_cam, atol=1e-7)
    assert a.dissipation_before > a.dissipation_after


def test_uncertainty_matches_the_spread_of_estimates() -> None:
    """The 1-sigma from the covariance agrees with the Monte Carlo scatter (within 30 %) for a
    fixed model (model choice adds its own scatter: see test_noise's coverage)."""
    rng = np.random.default_rng(5)
    base = make_problem(15, rng)
    est, std = [], []
    for _ in range(150):
        p_cam = base.p_cam_true + rng.standard_normal(base.p_cam.shape) * base.sigma
        cal = calibrate(p_cam, base.T_base_flange, sigma=base.sigma, leave_one_out=False, correction="rigid")
        est.append(cal.translation)
        std.append(cal.std_translation_mm)
    mc = 1e3 * np.std(np.array(est), axis=0)
    np.testing.assert_allclose(np.mean(std, axis=0), mc, rtol=0.3)


def test_robust_loss_resists_a_gross_error() -> None:
    pr = make_problem(14, np.random.default_rng(8))
    p_cam = pr.p_cam.copy()
    p_cam[4] += [0.03, 0.0, 0.05]
    plain = solve(p_cam, pr.T_base_flange, pr.sigma)
    robust = solve(p_cam, pr.T_base_flange, pr.sigma, loss="cauchy", loss_scale=3.0)
    e_plain = np.linalg.norm(plain.t - pr.T_flange_cam[:3, 3])
    e_robust = np.linalg.norm(robust.t - pr.T_flange_cam[:3, 3])
    assert e_robust < 0.25 * e_plain
    assert robust.weights[4] < 0.05
