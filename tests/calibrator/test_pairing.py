"""Pairing blobs with flange poses: interpolation (slerp), tolerance, still check."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_calibrator.pairing import NotPaired, PairingOptions, PoseBuffer
from sofia_schemas.transforms import interpolate_poses, rotation_angle


def pose(x: float, yaw_deg: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    T[:3, 3] = [x, 0.0, 0.5]
    return T


def test_interpolation_is_linear_and_slerp() -> None:
    T = interpolate_poses(pose(0.0, 0.0), pose(0.1, 40.0), 0.25)
    assert T.shape == (4, 4)
    np.testing.assert_allclose(T[:3, 3], [0.025, 0.0, 0.5])
    assert np.degrees(rotation_angle(T[:3, :3])) == pytest.approx(10.0)
    Ts = interpolate_poses(pose(0.0, 0.0), pose(0.1, 40.0), np.array([0.0, 0.5, 1.0]))  # several at once
    assert Ts.shape == (3, 4, 4)
    np.testing.assert_allclose(np.degrees(rotation_angle(Ts[:, :3, :3])), [0.0, 20.0, 40.0], atol=1e-9)
    np.testing.assert_allclose(Ts[[0, 2]], [pose(0.0, 0.0), pose(0.1, 40.0)], atol=1e-12)


def test_pose_at_and_still_check() -> None:
    buf = PoseBuffer()
    opts = PairingOptions(tolerance_ns=10_000_000, max_gap_ns=200_000_000, still_window_ns=100_000_000)
    for k, t in enumerate(range(0, 1_000_000_001, 100_000_000)):  # moving 1 cm / 100 ms for the first half
        buf.add(t, pose(min(k, 5) * 0.01, 0.0))
    np.testing.assert_allclose(buf.pose_at(150_000_000, opts)[:3, 3], [0.015, 0.0, 0.5])
    with pytest.raises(NotPaired, match="moving"):
        buf.pair(200_000_000, opts)
    T = buf.pair(800_000_000, opts)  # at rest since 0.5 s
    np.testing.assert_allclose(T[:3, 3], [0.05, 0.0, 0.5])
    with pytest.raises(NotPaired, match=r"nearest flange pose is 500\.0 ms from 1500000000 ns"):
        buf.pose_at(1_500_000_000, opts)
    with pytest.raises(NotPaired, match="no flange pose"):
        PoseBuffer().pose_at(0, opts)
