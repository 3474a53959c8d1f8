"""Pure planning of the autonomous calibration: inverse kinematics, views, information, the
camera's rotation from the table."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from sofia_arm import plan
from sofia_arm.poses import Q_HOME, Reach, in_image, look_at, solve_ik, views_of
from sofia_calibrator.fitting.diagnostics import check_motion
from sofia_calibrator.fitting.noise import sample_noise
from sofia_schemas.kinematics import panda_fk
from sofia_schemas.transforms import apply, invert, rotation_angle

K = np.array([[615.0, 0.0, 319.5], [0.0, 615.0, 239.5], [0.0, 0.0, 1.0]])


def test_ik_recovers_reachable_poses() -> None:
    """FK of random joints inside the margins, then IK from home: the same flange pose, within the
    joint limits. IK from 6 random restarts misses about 1.5 % of such poses (2 of 127 for seeds
    0-399), so the claim is a rate over fixed seeds, and every pose it solves must be exact."""
    reach, solved, tried = Reach(), 0, 0
    for seed in range(300):
        rng = np.random.default_rng(seed)
        T = panda_fk(rng.uniform(reach.q_lo + 0.2, reach.q_hi - 0.2))
        if not reach.in_box(T[:3, 3])[0]:
            continue
        tried += 1
        ik = solve_ik(T, Q_HOME, reach, rng=rng)
        if not ik.ok:
            continue
        solved += 1
        T_ik = panda_fk(ik.q)
        assert np.linalg.norm(T_ik[:3, 3] - T[:3, 3]) < 1e-4, seed
        assert np.degrees(rotation_angle(T_ik[:3, :3].T @ T[:3, :3])) < 0.02, seed
        assert np.all(ik.q >= reach.q_lo - 1e-9) and np.all(ik.q <= reach.q_hi + 1e-9), seed
    assert tried >= 80 and solved >= 0.97 * tried, (solved, tried)


def test_ik_refuses_outside_the_box_and_out_of_reach() -> None:
    T = panda_fk(Q_HOME)
    far = T.copy()
    far[:3, 3] = [0.5, 0.0, 1.5]
    r = solve_ik(far, Q_HOME)
    assert not r.ok and "outside the workspace box" in r.reason
    wide = Reach(box_min=(-2, -2, -2), box_max=(2, 2, 2))
    too_far = T.copy()
    too_far[:3, 3] = [1.2, 0.0, 0.3]  # beyond the Panda's 0.855 m reach
    r = solve_ik(too_far, Q_HOME, wide, n_random_seeds=2)
    assert not r.ok and "no joint solution" in r.reason


def test_views_look_at_the_target_from_the_asked_distance() -> None:
    target = np.array([0.5, 0.1, 0.0])
    T_bc = views_of(
        target, np.array([0.0, 30.0]), np.array([0.0, 90.0]), np.array([0.3, 0.6]), np.array([0.0, 120.0])
    )
    assert T_bc.shape == (16, 4, 4)
    p_cam = apply(invert(T_bc), np.broadcast_to(target, (16, 3)))
    np.testing.assert_allclose(p_cam[:, :2], 0.0, atol=1e-9)  # on the optical axis
    assert set(np.round(p_cam[:, 2], 6)) == {0.3, 0.6}
    assert in_image(p_cam, K, (640, 480), 40).all()
    off = look_at(np.array([0.5, 0.1, 0.5]), np.array([0.9, 0.1, 0.4]), 0.0)  # target 76 deg off
    assert not in_image(apply(invert(off), target[None]), K, (640, 480), 40)[0]


def test_information_matches_the_calibrators_covariance_model() -> None:
    """Predicted 1-sigma of the camera offset against the spread of fits of simulated samples."""
    from sofia_calibrator import calibrate

    rng = np.random.default_rng(3)
    T_fc = np.eye(4)
    T_fc[:3, :3] = Rotation.from_euler("zx", [90, -8], degrees=True).as_matrix()
    T_fc[:3, 3] = [0.065, 0.0, 0.045]
    p_base = np.array([0.5, 0.0, 0.0])
    T_bc = views_of(p_base, np.array([10.0, 30.0]), np.array([0.0, 120.0, 240.0]), np.array([0.3, 0.55]),
                    np.array([0.0]), np.array([[8.0, 0.0], [0.0, -6.0]]))  # fmt: skip
    T_bf = T_bc @ invert(T_fc)
    info = plan.information(T_bf, T_fc, p_base).sum(axis=0)
    predicted = plan.translation_sigma_mm(info)
    p_true = apply(invert(T_bc), np.broadcast_to(p_base, (len(T_bc), 3)))
    errors = []
    for _ in range(40):
        p = p_true + sample_noise(p_true, rng)
        cal = calibrate(
            p, T_bf, sigma="depth", exclude_outliers=False, leave_one_out=False, correction="rigid"
        )
        errors.append(1e3 * (cal.T_flange_cam[:3, 3] - T_fc[:3, 3]))
    measured = np.std(errors, axis=0)
    np.testing.assert_allclose(measured, predicted, rtol=0.35)


def test_ranking_prefers_views_that_add_a_new_rotation_axis() -> None:
    """After views rotated about one axis only, the best next view rotates about another, and the
    chosen set passes the calibrator's observability check."""
    T_fc = np.eye(4)
    T_fc[:3, 3] = [0.05, 0.0, 0.04]
    p_base = np.array([0.5, 0.0, 0.0])
    taken = views_of(
        p_base, np.array([0.0, 30.0]), np.array([0.0]), np.array([0.4]), np.array([0.0])
    ) @ invert(T_fc)
    cands = views_of(
        p_base, np.array([30.0]), np.array([0.0, 90.0]), np.array([0.4]), np.array([0.0])
    ) @ invert(T_fc)
    info = plan.prior_information() + plan.information(taken, T_fc, p_base).sum(axis=0)
    ranked = plan.rank_candidates(info, cands, T_fc, p_base)
    assert ranked.order[0] == 1  # the one tilted about the other axis
    assert ranked.scores[0] < ranked.scores[1]
    check_motion(np.concatenate([taken, cands[1:]]))  # raises DegenerateMotion if not observable


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_rotation_from_the_table_recovers_any_camera_rotation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    R_fc = Rotation.random(random_state=rng).as_matrix()
    T_bf = np.tile(np.eye(4), (3, 1, 1))
    T_bf[:, :3, :3] = Rotation.from_euler("xy", [[180, 0], [205, 0], [180, 25]], degrees=True).as_matrix()
    normals_cam = np.einsum("ji,nkj,k->ni", R_fc, T_bf[:, :3, :3], [0.0, 0.0, 1.0])  # R_bc^T e_z
    normals_cam += rng.normal(0, 1e-3, normals_cam.shape)
    R = plan.rotation_from_table(T_bf, normals_cam / np.linalg.norm(normals_cam, axis=1, keepdims=True))
    assert np.degrees(rotation_angle(R.T @ R_fc)) < 0.5


def test_table_plane_of_a_cloud_faces_the_camera() -> None:
    rng = np.random.default_rng(0)
    u, v = np.meshgrid(np.linspace(-0.3, 0.3, 80), np.linspace(-0.2, 0.2, 60))
    n_true = np.array([0.1, -0.2, -1.0]) / np.linalg.norm([0.1, -0.2, -1.0])
    d = 0.45
    pts = np.stack([u, v, np.zeros_like(u)], -1).reshape(-1, 3)
    # a plane with normal n_true at distance d: points p with n.p = -d
    basis = np.linalg.svd(n_true[None])[2][1:]
    pts = pts[:, :2] @ basis - d * n_true + rng.normal(0, 5e-4, (len(pts), 3)) * n_true
    pts[:200] += 0.05 * n_true  # an object on the table
    pts[200:300] = np.nan
    plane = plan.table_plane_cam(pts.reshape(60, 80, 3))
    assert plane is not None
    n, dist = plane
    assert np.degrees(np.arccos(np.clip(n @ n_true, -1, 1))) < 0.5
    assert dist == pytest.approx(d, abs=2e-3)
    assert plan.table_plane_cam(np.full((10, 10, 3), np.nan)) is None


def test_intrinsics_fitted_to_an_organized_cloud() -> None:
    v, u = np.mgrid[0:480, 0:848]
    z = 0.4 + 0.1 * u / 848  # a slanted plane
    p = np.stack([(u - 424.0) / 610.0 * z, (v - 241.0) / 612.0 * z, z], -1)
    p[:100] = np.nan
    K_fit = plan.intrinsics_of(p)
    assert K_fit is not None
    np.testing.assert_allclose(K_fit[[0, 1, 0, 1], [0, 1, 2, 2]], [610.0, 612.0, 424.0, 241.0], rtol=1e-6)
    assert plan.intrinsics_of(np.full((48, 64, 3), np.nan)) is None
