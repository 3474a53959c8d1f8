"""The camera-correction model: the message's apply(), the model chosen by the data, the detector
applying it once, old results still parsing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator import calibrate, to_message, to_yaml
from sofia_calibrator.fitting.simulate import make_problem
from sofia_schemas.messages import CalibrationResult
from sofia_schemas.messages.calibration import (
    CORRECTION_APPLIED_ATTACHMENT,
    CameraCorrection,
    correction_applied,
    read_calibration_file,
)


def test_apply_is_vectorised_keeps_nan_and_leaves_the_input() -> None:
    p = np.array([[0.1, -0.2, 0.5], [np.nan, np.nan, np.nan], [0.0, 0.0, 1.0]])
    before = p.copy()
    depth = CameraCorrection(model="depth_scale", depth_scale=0.95).apply(p)
    np.testing.assert_allclose(depth[[0, 2]], [[0.1, -0.2, 0.475], [0.0, 0.0, 0.95]])
    assert np.isnan(depth[1]).all()
    ray = CameraCorrection(model="ray_scale", depth_scale=0.95).apply(p)
    np.testing.assert_allclose(ray[0], 0.95 * p[0])
    off = CameraCorrection(model="depth_scale_offset", depth_scale=1.0, depth_offset_m=0.01).apply(p)
    np.testing.assert_allclose(off[0], [0.1, -0.2, 0.51])
    np.testing.assert_array_equal(CameraCorrection().apply(p)[0], p[0])
    np.testing.assert_array_equal(p, before)
    organized = np.ones((4, 5, 3))
    assert CameraCorrection(model="depth_scale", depth_scale=2.0).apply(organized)[..., 2].max() == 2.0
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3\)"):
        CameraCorrection().apply(np.ones((4, 2)))
    with pytest.raises(ValueError):
        CameraCorrection(model="depth_scale", depth_scale=-1.0)
    with pytest.raises(ValueError):
        CameraCorrection(model="fisheye")  # type: ignore[arg-type]


def test_an_old_result_without_a_correction_still_parses_as_identity() -> None:
    msg = to_message(calibrate(*_problem(12, 3, 1.0)[:2]))
    body = msg.model_dump(mode="json")
    for k in ("camera_correction", "correction_models", "correction_reason", "noise_mm", "covariance",
              "criterion_advice"):  # fmt: skip
        body.pop(k)
    old = CalibrationResult.model_validate(body)
    assert old.camera_correction.is_identity and old.camera_correction.model == "rigid"


def test_the_attachment_flag() -> None:
    assert correction_applied(CORRECTION_APPLIED_ATTACHMENT)
    assert not correction_applied(None) and not correction_applied(b"") and not correction_applied(b"other")


def _problem(n: int, seed: int, scale: float, model: str = "depth_scale", robot_mm: float = 1.5):
    """(p_cam measured, T_base_flange, truth) with the camera's depth reading 1/scale long and
    isotropic robot noise plus the D435's."""
    rng = np.random.default_rng(seed)
    pr = make_problem(n, rng)
    true = pr.p_cam_true + rng.standard_normal(pr.p_cam.shape) * robot_mm * 1e-3
    measured = CameraCorrection(model=model, depth_scale=1.0 / scale).apply(true)  # type: ignore[arg-type]
    measured = measured + (pr.p_cam - pr.p_cam_true)
    return measured, pr.T_base_flange, pr


@pytest.mark.parametrize("model", ["depth_scale", "ray_scale"])
def test_a_known_scale_is_found_and_chosen(model: str) -> None:
    asked = 0
    for seed in range(20):
        p, T, pr = _problem(15, seed, 0.95, model)
        cal = calibrate(p, T)  # auto: rigid or depth_scale, the nearest to a ray scale
        assert cal.correction.model == "depth_scale", cal.correction_reason
        exact = calibrate(p, T, correction=model)
        assert np.linalg.norm(exact.translation - pr.T_flange_cam[:3, 3]) < 0.01
        assert exact.correction.depth_scale_sigma is not None
        assert abs(exact.correction.depth_scale - 0.95) < 4 * exact.correction.depth_scale_sigma + 0.003
        asked += abs(exact.correction.depth_scale - 0.95) < 3 * exact.correction.depth_scale_sigma
    assert asked >= 17


def test_a_rigid_camera_rarely_gets_a_correction() -> None:
    chosen = [calibrate(*_problem(11, 100 + s, 1.0)[:2]).correction.model for s in range(150)]
    assert chosen.count("rigid") >= 146  # nominal 0.1 %: at most 4 of 150


def test_map_to_base_applies_the_full_model() -> None:
    p, T, _ = _problem(14, 7, 0.95)
    cal = calibrate(p, T)
    mapped = cal.map_to_base(p, T)
    assert mapped.shape == (14, 3)
    np.testing.assert_allclose(
        np.linalg.norm(mapped - cal.p_base, axis=1), cal.residuals_mm / 1e3, atol=1e-12
    )
    one = cal.map_to_base(p[:1], T[0])  # one (4, 4) pose broadcasts
    np.testing.assert_allclose(one, mapped[:1])
    text = cal.correction.describe()
    assert "reads 5." in text and "long" in text and "0.95" in text
    assert "camera correction: depth_scale" in to_yaml(to_message(cal))


def test_the_detector_applies_the_correction_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import sofia_detector.service as svc
    from sofia_detector.service import Detector, ServiceConfig
    from sofia_runtime.zenoh_config import ZenohOptions
    from sofia_schemas import Board, pointcloud

    p, T, _ = _problem(12, 9, 0.95)
    cal = calibrate(p, T)
    result = to_message(cal)
    path = tmp_path / "cal.json"
    path.write_text(result.model_dump_json())
    assert read_calibration_file(path)[1] == cal.correction
    (tmp_path / "cal.yaml").write_text(to_yaml(result))
    assert read_calibration_file(tmp_path / "cal.yaml")[1].depth_scale == pytest.approx(
        cal.correction.depth_scale
    )
    det = Detector(ServiceConfig(Board.default(), "panda", ZenohOptions(), transform_file=path), {})
    det.flange.add(0, T[0])
    seen: list[np.ndarray] = []
    orig = svc.detect

    def spy(points: np.ndarray, *a: object, **k: object) -> object:
        seen.append(np.array(points))
        return orig(points, *a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(svc, "detect", spy)
    payload = bytes(pointcloud.encode_points(p[:1].astype(np.float32), stamp_ns=0, frame_id="cam"))
    for corrected in (False, True):  # the producer did not / did apply it (Zenoh attachment)
        det.detect_payload(payload, True, "test/camera", corrected)
    np.testing.assert_allclose(seen[0][0], cal.map_to_base(p[:1], T[0])[0], atol=1e-6)
    np.testing.assert_allclose(seen[1][0], cal.map_to_base(p[:1] / [1, 1, cal.correction.depth_scale], T[0])[0],
                               atol=1e-6)  # fmt: skip
