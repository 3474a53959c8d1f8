"""Quaternions to rotation matrices: SciPy's result, bit for bit, without SciPy's per-call overhead
(a flange pose arrives 30 times a second); bad quaternions refused with what was wrong."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_schemas.transforms import quat_xyzw_to_matrix


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
