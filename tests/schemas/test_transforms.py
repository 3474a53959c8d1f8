"""Quaternions to rotation matrices and back (SciPy's ``Rotation`` behind both): round trips with
w >= 0, the shapes kept, bad quaternions refused with what was wrong, matrices that are no rotation
projected or refused."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_schemas.transforms import make_transform, matrix_to_quat_xyzw, quat_xyzw_to_matrix


def test_quaternions_round_trip_with_w_non_negative() -> None:
    rng = np.random.default_rng(7)
    q = rng.normal(size=(5000, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R = quat_xyzw_to_matrix(q * (1 + rng.uniform(-5e-4, 5e-4, (5000, 1))))  # within the tolerance
    assert np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max() < 1e-12
    assert np.all(np.linalg.det(R) > 0)
    back = matrix_to_quat_xyzw(R)
    assert np.all(back[:, 3] >= 0)
    assert np.abs(back - np.where(q[:, 3:4] < 0, -q, q)).max() < 1e-12
    p = rng.normal(size=3)  # q rotates p as R does
    assert np.allclose(R[0] @ p, Rotation.from_quat(q[0]).apply(p), atol=1e-14)
    assert quat_xyzw_to_matrix(q[:1]).shape == (1, 3, 3) and quat_xyzw_to_matrix(q[0]).shape == (3, 3)
    assert matrix_to_quat_xyzw(R[:1]).shape == (1, 4) and matrix_to_quat_xyzw(R[0]).shape == (4,)
    T = make_transform(np.array([0.1, 0.2, 0.3]), q[0])
    assert np.abs(T[:3, :3] - R[0]).max() < 1e-12
    assert np.array_equal(T[3], [0.0, 0.0, 0.0, 1.0]) and np.array_equal(T[:3, 3], [0.1, 0.2, 0.3])


def test_half_turns_keep_w_non_negative() -> None:
    turns = [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    down = [Rotation.from_euler("zx", [yaw, np.pi]).as_matrix() for yaw in np.linspace(-4.0, 4.0, 41)]
    R = np.array(turns + down)
    q = matrix_to_quat_xyzw(R)
    assert np.all(q[:, 3] >= 0) and np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.abs(quat_xyzw_to_matrix(q) - R).max() < 1e-12


@pytest.mark.parametrize(
    ("q", "match"),
    [(np.zeros(3), r"shape \(4,\) or \(n, 4\)"),
     (np.array([0.0, 0.0, np.nan, 1.0]), "non-finite"),
     (np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 2.0]]), "quaternion 1 has norm 2.000000")],
)  # fmt: skip
def test_bad_quaternions_are_refused(q: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        quat_xyzw_to_matrix(q)


def test_matrices_that_are_no_rotation_are_projected_or_refused() -> None:
    R = Rotation.random(random_state=4).as_matrix()
    q = matrix_to_quat_xyzw(R * 1.001)  # not orthonormal: projected onto the rotations
    assert np.isclose(np.linalg.norm(q), 1.0) and np.abs(q - matrix_to_quat_xyzw(R)).max() < 1e-9
    for reflection in (np.diag([1.0, 1.0, -1.0]), -R):
        with pytest.raises(ValueError, match="Non-positive determinant"):
            matrix_to_quat_xyzw(reflection)
    with pytest.raises(ValueError), np.errstate(invalid="ignore"):
        matrix_to_quat_xyzw(np.full((3, 3), np.nan))
    with pytest.raises(ValueError):
        matrix_to_quat_xyzw(np.eye(4))


def test_pose_gap_is_the_translation_and_the_angle_between_two_poses() -> None:
    from sofia_schemas.transforms import pose_gap

    rng = np.random.default_rng(0)
    for angle in (0.0, 1e-9, 1e-4, 0.3, np.pi - 1e-6):
        axis = rng.standard_normal(3)
        T_a = make_transform(rng.uniform(-1, 1, 3), Rotation.random(random_state=rng).as_quat())
        T_b = T_a.copy()
        T_b[:3, :3] = T_a[:3, :3] @ Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix()
        T_b[:3, 3] += [0.003, -0.004, 0.0]
        dt, dr = pose_gap(T_a, T_b)
        assert dt == pytest.approx(0.005, abs=1e-12)
        assert dr == pytest.approx(angle, abs=1e-12 + 1e-9 * angle), angle  # small angles kept exact too
        assert pose_gap(T_b, T_a) == pytest.approx((dt, dr), abs=1e-12)
