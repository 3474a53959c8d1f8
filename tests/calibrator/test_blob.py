"""Blob extraction from organized RGB-D clouds: rendered sessions and the frames to reject."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from sofia_calibrator import BlobAmbiguous, BlobCutByEdge, BlobNotFound, calibrate
from sofia_calibrator.blob import find_blob
from sofia_calibrator.errors import BlobNoDepth, CalibrationError, InputMismatch

H, W, F = 480, 640, 615.0


def flat_frame(discs: list[tuple[float, float, float]], z: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """A white sheet filling the view at depth ``z`` with dark discs (u, v, radius px)."""
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    points = np.stack([(u - 319.5) / F * z, (v - 239.5) / F * z, np.full_like(u, z)], axis=2)
    rgb = np.full((H, W, 3), 240, np.uint8)
    for uc, vc, r in discs:
        rgb[(u - uc) ** 2 + (v - vc) ** 2 <= r * r] = 25
    return points.astype(np.float32), rgb


def test_rendered_session_blobs_are_found_within_a_millimetre() -> None:
    from sofia_replay.synth.calibration import make_calibration_session

    session = make_calibration_session(6, np.random.default_rng(7))
    found = [find_blob(f.points_cam, f.rgb) for f in session.frames]
    errors_mm = [
        1e3 * np.linalg.norm(b.p_cam - f.p_cam_true) for b, f in zip(found, session.frames, strict=True)
    ]
    assert max(errors_mm) < 1.0, errors_mm
    assert all(0.5 < b.confidence <= 1.0 for b in found)
    p_cam = np.array([b.p_cam for b in found])
    T = np.array([f.T_base_flange for f in session.frames])
    cal = calibrate(p_cam, T)
    assert np.linalg.norm(cal.translation - session.T_flange_cam[:3, 3]) < 0.005


def test_flat_frame_centre_is_exact() -> None:
    points, rgb = flat_frame([(400.0, 200.0, 20.0)])
    b = find_blob(points, rgb)
    np.testing.assert_allclose(b.p_cam, [(400 - 319.5) / F * 0.5, (200 - 239.5) / F * 0.5, 0.5], atol=2e-4)


def test_blob_with_missing_depth_uses_the_sheet_plane() -> None:
    points, rgb = flat_frame([(300.0, 260.0, 18.0)])
    v, u = np.mgrid[0:H, 0:W]
    points[(u - 300) ** 2 + (v - 260) ** 2 <= 18**2] = np.nan  # dark surfaces often lose depth
    b = find_blob(points, rgb)
    np.testing.assert_allclose(b.p_cam, [(300 - 319.5) / F * 0.5, (260 - 239.5) / F * 0.5, 0.5], atol=2e-4)


def test_rejections_say_why() -> None:
    with pytest.raises(BlobNotFound, match="no pixel darker"):
        find_blob(*flat_frame([]))
    with pytest.raises(BlobCutByEdge, match="touches the image edge"):
        find_blob(*flat_frame([(5.0, 240.0, 20.0)]))
    with pytest.raises(BlobAmbiguous, match="2 dark blobs"):
        find_blob(*flat_frame([(200.0, 240.0, 20.0), (450.0, 240.0, 18.0)]))
    points, rgb = flat_frame([(300.0, 240.0, 20.0)])
    with pytest.raises(BlobNoDepth):
        find_blob(np.full_like(points, np.nan), rgb)
    with pytest.raises(InputMismatch, match=r"organized cloud \(H, W, 3\)"):
        find_blob(points.reshape(-1, 3), rgb)
    assert issubclass(BlobAmbiguous, CalibrationError)


def test_a_view_all_dark_is_no_blob_and_raises_no_warning() -> None:
    points, rgb = flat_frame([])
    rgb[:] = 20  # lens cap on, or the sheet out of the light: one dark region with nothing around it
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "Mean of empty slice" from the empty ring around it
        with pytest.raises(BlobNotFound, match="none of 1 dark regions is a blob"):
            find_blob(points, rgb)


def test_small_specks_are_not_ambiguous() -> None:
    b = find_blob(*flat_frame([(300.0, 240.0, 20.0), (500.0, 100.0, 4.0)]))
    assert b.n_pixels > 1000


def test_glare_on_the_rim_neither_shifts_the_blob_nor_keeps_full_confidence() -> None:
    uc, vc, r = 300.0, 240.0, 20.0
    clean = find_blob(*flat_frame([(uc, vc, r)]))
    points, rgb = flat_frame([(uc, vc, r)])
    v, u = np.mgrid[0:H, 0:W]
    spot = ((u - uc) ** 2 + (v - vc) ** 2 <= r * r) & (u - uc > 10.0)  # a crescent of the rim glares
    rgb[spot] = 255
    points[spot] = np.nan  # specular pixels lose their depth too
    glared = find_blob(points, rgb)
    truth = np.array([(uc - 319.5) / F * 0.5, (vc - 239.5) / F * 0.5, 0.5])
    # the plain centroid of the dark pixels that are left is off by more than a millimetre
    dark = ((u - uc) ** 2 + (v - vc) ** 2 <= r * r) & ~spot
    centroid = np.array([(u[dark].mean() - 319.5) / F * 0.5, (v[dark].mean() - 239.5) / F * 0.5, 0.5])
    assert np.linalg.norm(centroid - truth) > 1e-3
    assert np.linalg.norm(glared.p_cam - truth) < 3e-4
    assert glared.confidence < 0.9 * clean.confidence
    np.testing.assert_allclose(clean.p_cam, truth, atol=2e-4)


def tilted_frame(c_cam: np.ndarray, normal: np.ndarray, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A white sheet through ``c_cam`` (3,) with unit ``normal`` (3,), camera frame, metres, and a
    dark disc of ``radius_m`` centred on ``c_cam``: every pixel's ray cast onto the sheet exactly."""
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = np.stack([(u - 319.5) / F, (v - 239.5) / F, np.ones_like(u)], axis=2)
    points = rays * ((normal @ c_cam) / (rays @ normal))[..., None]
    rgb = np.full((H, W, 3), 240, np.uint8)
    rgb[np.linalg.norm(points - c_cam, axis=2) <= radius_m] = 25
    return points.astype(np.float32), rgb


@pytest.mark.parametrize("tilt_deg", [0.0, 25.0, 45.0, 60.0])
def test_tilted_close_disc_centre_has_no_perspective_bias(tilt_deg: float) -> None:
    """The image of a tilted disc's centre is not the centre of its image: the pixel centroid's ray
    lands ~0.5 mm towards the camera at 0.29 m and 45 deg; the plane-area centroid does not."""
    c_cam = np.array([0.03, -0.02, 0.29])
    a = np.radians(tilt_deg)
    normal = np.array([np.sin(a), 0.0, -np.cos(a)])  # the sheet turned about the camera's y axis
    b = find_blob(*tilted_frame(c_cam, normal, 0.02))
    err_mm = 1e3 * np.linalg.norm(b.p_cam - c_cam)
    assert err_mm < 0.08, (err_mm, b.p_cam - c_cam)


def test_stereo_depth_noise_does_not_bias_a_tilted_blob() -> None:
    """Stereo noise, constant in disparity (inverse depth) and along the rays, leaves a close,
    tilted blob unbiased (the pixel centroid's ray was ~0.5 mm off here, noise or not)."""
    c_cam = np.array([0.0, 0.0, 0.29])
    a = np.radians(40.0)
    normal = np.array([0.0, np.sin(a), -np.cos(a)])
    points, rgb = tilted_frame(c_cam, normal, 0.015)
    rng = np.random.default_rng(3)
    errors_mm = []
    for _ in range(8):
        inv_depth = 1.0 / points[..., 2] + rng.normal(0.0, 0.004, points.shape[:2])  # 1/m: D435 at 0.29 m
        noisy = points / points[..., 2:3] / inv_depth[..., None]
        errors_mm.append(1e3 * (find_blob(noisy.astype(np.float32), rgb).p_cam - c_cam))
    mean_mm = np.mean(errors_mm, axis=0)
    assert np.linalg.norm(mean_mm) < 0.1, mean_mm
