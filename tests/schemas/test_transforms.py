"""Quaternions to rotation matrices and back: SciPy's results, bit for bit, without SciPy's per-call
overhead (a flange pose arrives 30 times a second, a pick target is computed per detection); bad
quaternions refused with what was wrong, matrices that are no rotation handled as SciPy does."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_schemas.transforms import SCIPY_FROM, matrix_to_quat_xyzw, quat_xyzw_to_matrix


def test_quaternion_matrices_are_scipys_bits() -> None:
    rng = np.random.default_rng(7)
    q = rng.normal(size=(5000, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= 1 + rng.uniform(-5e-4, 5e-4, (5000, 1))  # within the tolerance: normalised, as SciPy does
    assert np.array_equal(quat_xyzw_to_matrix(q), Rotation.from_quat(q).as_matrix())
    assert np.array_equal(quat_xyzw_to_matrix(q[3]), Rotation.from_quat(q[3]).as_matrix())
    assert quat_xyzw_to_matrix(q[:1]).shape == (1, 3, 3) and quat_xyzw_to_matrix(q[0]).shape == (3, 3)


@pytest.mark.parametrize(
    ("q", "match"),
    [(np.zeros(3), r"shape \(4,\) or \(n, 4\)"),
     (np.array([0.0, 0.0, np.nan, 1.0]), "non-finite"),
     (np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 2.0]]), "quaternion 1 has norm 2.000000")],
)  # fmt: skip
def test_bad_quaternions_are_refused(q: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        quat_xyzw_to_matrix(q)


def _scipy_quat(R: np.ndarray) -> np.ndarray:
    q = Rotation.from_matrix(R).as_quat()
    return np.where(q[..., 3:4] < 0, -q, q)


def test_rotation_quaternions_are_scipys_bits() -> None:
    turns = [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    down = [Rotation.from_euler("zx", [yaw, np.pi]).as_matrix() for yaw in np.linspace(-4.0, 4.0, 41)]
    R = np.concatenate([Rotation.random(3000, random_state=3).as_matrix(), turns, down])
    ours = np.array([matrix_to_quat_xyzw(r) for r in R])  # one at a time: the written-out formula
    assert np.array_equal(ours, _scipy_quat(R))
    assert np.all(ours[:, 3] >= 0)
    few, many = R[:SCIPY_FROM], R[: SCIPY_FROM + 1]  # batches: the formula, then SciPy's loop
    assert np.array_equal(matrix_to_quat_xyzw(few), _scipy_quat(few))
    assert np.array_equal(matrix_to_quat_xyzw(many), _scipy_quat(many))
    assert matrix_to_quat_xyzw(R[:1]).shape == (1, 4) and matrix_to_quat_xyzw(R[0]).shape == (4,)


def test_matrices_that_are_no_rotation_go_through_scipy() -> None:
    R = Rotation.random(random_state=4).as_matrix()
    scaled = R * 1.001  # not orthonormal: SciPy projects it onto the rotations
    assert np.array_equal(matrix_to_quat_xyzw(scaled), _scipy_quat(scaled))
    for reflection in (np.diag([1.0, 1.0, -1.0]), -R):
        with pytest.raises(ValueError, match="Non-positive determinant"):
            matrix_to_quat_xyzw(reflection)
    with pytest.raises(ValueError), np.errstate(invalid="ignore"):
        matrix_to_quat_xyzw(np.full((3, 3), np.nan))
    with pytest.raises(ValueError):
        matrix_to_quat_xyzw(np.eye(4))
