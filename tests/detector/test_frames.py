"""Flange pose history, flange->camera transform files, camera clouds into the base frame."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_detector import TransformUnavailable
from sofia_detector.frames import FlangeHistory, points_to_base
from sofia_schemas.messages import FlangePose
from sofia_schemas.transforms import make_transform, matrix_to_quat_xyzw


def _T(rotvec, t) -> np.ndarray:  # type: ignore[no-untyped-def]
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def test_history_interpolates_between_bracketing_poses() -> None:
    h = FlangeHistory(tolerance_ns=50_000_000)
    T0, T1 = _T([0, 0, 0], [0.0, 0.0, 0.5]), _T([0, 0, 0.2], [0.1, 0.0, 0.5])
    h.add(1_000_000_000, T0)
    h.add(1_040_000_000, T1)
    T = h.at(1_010_000_000)
    assert np.allclose(T[:3, 3], [0.025, 0, 0.5])
    assert Rotation.from_matrix(T[:3, :3]).as_rotvec() == pytest.approx([0, 0, 0.05])
    assert np.array_equal(h.at(1_040_000_000), T1)


def test_history_of_flange_poses_gives_the_matrices_of_a_history_of_matrices() -> None:
    """Poses added as received (``FlangePose``, converted only when asked) give the same matrices,
    exact, interpolated and nearest, as the same poses added as matrices."""
    rng = np.random.default_rng(3)
    stamps = np.arange(6) * 30_000_000 + 1_000_000_000
    Ts = [_T(rng.normal(0, 0.5, 3), rng.uniform(-0.5, 0.5, 3)) for _ in stamps]
    as_poses, as_matrices = FlangeHistory(tolerance_ns=20_000_000), FlangeHistory(tolerance_ns=20_000_000)
    for stamp, T in zip(stamps, Ts, strict=True):
        pose = FlangePose.from_matrix(T, int(stamp))
        as_poses.add(int(stamp), pose)
        as_matrices.add(int(stamp), pose.matrix())
    for stamp in (*stamps, stamps[2] + 12_345_678, stamps[-1] + 15_000_000):
        assert np.array_equal(as_poses.at(int(stamp)), as_matrices.at(int(stamp)))
    assert np.allclose(as_poses.at(int(stamps[1])), Ts[1], atol=1e-12)


def test_history_nearest_and_tolerance() -> None:
    h = FlangeHistory(tolerance_ns=20_000_000)
    h.add(2_000_000_000, _T([0, 0, 0], [1, 2, 3]))
    h.add(1_000_000_000, _T([0, 0, 0], [0, 0, 0]))  # out of order is fine
    assert np.allclose(h.at(2_010_000_000)[:3, 3], [1, 2, 3])
    with pytest.raises(
        TransformUnavailable,
        match=r"nearest flange pose is 40\.0 ms from 2040000000 ns \(tolerance 20\.0 ms\)",
    ):
        h.at(2_040_000_000)
    with pytest.raises(TransformUnavailable, match="no flange pose received yet"):
        FlangeHistory().at(5)


def test_points_to_base_matches_the_renderer(scenes) -> None:
    f = scenes["box"].frame
    T_base_cam = f.T_base_flange @ f.T_flange_cam
    points = points_to_base(f.render.points_cam, T_base_cam)
    assert points.shape == f.points_base.shape
    assert np.allclose(points, f.points_base, atol=1e-5, equal_nan=True)
    assert np.allclose(make_transform(T_base_cam[:3, 3], matrix_to_quat_xyzw(T_base_cam[:3, :3])), T_base_cam)


def test_a_pose_arriving_after_its_cloud_is_waited_for() -> None:
    """Poses and clouds travel on different keys: the cloud's pose may come a moment later."""
    history = FlangeHistory()
    T = np.eye(4)
    T[:3, 3] = (0.4, 0.1, 0.5)
    assert not history.wait_covered(1_000, 0.05)  # nothing arrives: times out
    threading.Timer(0.1, history.add, args=(1_000, T)).start()
    t0 = time.monotonic()
    assert history.wait_covered(1_000, 2.0)
    assert time.monotonic() - t0 < 1.0
    np.testing.assert_allclose(history.at(1_000), T)


def test_a_jump_back_in_time_starts_a_new_history() -> None:
    """Poses of another recording (or a restarted replay) are never mixed with the old ones."""
    history = FlangeHistory()
    T_old, T_new = np.eye(4), np.eye(4)
    T_old[:3, 3], T_new[:3, 3] = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    history.add(10_000_000_000, T_old)
    history.add(5_000_000_000, T_new)  # 5 s back: a new time line
    assert len(history) == 1
    np.testing.assert_allclose(history.at(5_000_000_000), T_new)
    history.add(5_000_000_000 - 10_000_000, T_old)  # 10 ms back: reordered, kept
    assert len(history) == 2
