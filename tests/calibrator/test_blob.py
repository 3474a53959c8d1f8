"""Blob extraction from organized RGB-D clouds: rendered sessions and the frames to reject."""

from __future__ import annotations

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
