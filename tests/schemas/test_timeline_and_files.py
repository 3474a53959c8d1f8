"""Stamped poses looked up at a stamp (:class:`PoseTimeline`, used by the detector and the
calibrator) and saved calibrations read back (:func:`read_calibration_file`, used by the detector
and the arm)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_schemas.files import FileContentError
from sofia_schemas.messages import FlangePose
from sofia_schemas.messages.calibration import CameraCorrection, read_calibration_file
from sofia_schemas.transforms import PoseTimeline, make_transform, matrix_to_quat_xyzw


def _T(yaw_deg: float, x: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    T[:3, 3] = (x, 0.2, 0.5)
    return T


def test_a_timeline_gives_the_exact_interpolated_or_nearest_pose() -> None:
    line = PoseTimeline(maxlen=3)
    line.add(2_000, _T(40.0, 0.4))
    line.add(1_000, FlangePose.from_matrix(_T(0.0, 0.0), 1_000))  # late, and a message: sorted in, converted
    assert line.stamps_ns == [1_000, 2_000]
    np.testing.assert_allclose(line.at(1_000, 0, 10_000), _T(0.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(line.at(1_250, 0, 1_000), _T(10.0, 0.1), atol=1e-12)  # slerp and linear
    np.testing.assert_allclose(line.at(1_250, 300, 999), _T(0.0, 0.0), atol=1e-12)  # gap too wide: nearest
    np.testing.assert_allclose(line.at(2_100, 100, 1_000), _T(40.0, 0.4), atol=1e-12)
    with pytest.raises(
        LookupError, match=r"nearest flange pose is 0\.0 ms from 2101 ns \(tolerance 0\.0 ms\)"
    ):
        line.at(2_101, 100, 1_000)
    line.add(3_000, _T(0.0, 0.0))
    line.add(4_000, _T(0.0, 0.0))  # beyond maxlen: the oldest goes
    assert line.stamps_ns == [2_000, 3_000, 4_000] and len(line) == 3
    line.clear()
    with pytest.raises(LookupError, match="no flange pose received yet"):
        line.at(0, 1, 1)


def test_a_saved_calibration_reads_back_in_either_form(tmp_path: Path) -> None:
    T = _T(30.0, 0.05)
    (tmp_path / "m.json").write_text(
        json.dumps({"matrix": T.tolist(), "camera_correction": {"model": "depth_scale", "depth_scale": 0.95}})
    )
    q = matrix_to_quat_xyzw(T[:3, :3]).tolist()
    (tmp_path / "q.yaml").write_text(f"translation: {T[:3, 3].tolist()}\nquaternion_xyzw: {q}\n")
    T_m, corr_m = read_calibration_file(tmp_path / "m.json")
    T_q, corr_q = read_calibration_file(tmp_path / "q.yaml")
    np.testing.assert_allclose(T_m, T, atol=1e-12)
    np.testing.assert_allclose(T_q, make_transform(T[:3, 3], np.array(q)), atol=1e-12)
    assert corr_m.depth_scale == 0.95 and corr_q == CameraCorrection()


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("camera_correction: {depth_scale: -1}\nmatrix: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]",
         "camera_correction.depth_scale: Input should be greater than 0"),
        ("matrix: [[1, 0], [0, 1]]", "shape (4, 4)"),
        ("translation: [0, 0]\nquaternion_xyzw: [0, 0, 0, 1]", "translation must be 3 numbers"),
        ("foo: 1", "needs 'matrix' or 'translation' + 'quaternion_xyzw'"),
    ],
)  # fmt: skip
def test_a_bad_calibration_file_gets_one_line_naming_it(tmp_path: Path, text: str, needle: str) -> None:
    path = tmp_path / "cal.yaml"
    path.write_text(text)
    with pytest.raises(FileContentError) as e:
        read_calibration_file(path)
    assert str(e.value).startswith(str(path)) and needle in str(e.value) and "\n" not in str(e.value)
