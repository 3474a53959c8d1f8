"""Objects of which depth sees only slivers, placed from their colour silhouette and height."""

from __future__ import annotations

import numpy as np
from sofia_detector import detect
from sofia_detector.objects.silhouette import fit_camera, footprint, on_plane
from sofia_replay.synth.realism import bench_frame
from sofia_schemas import Board

BOARD = Board.default()


def _camera(eye: np.ndarray, target: np.ndarray, f: float = 600.0) -> np.ndarray:
    """(3, 4) pinhole at ``eye`` looking at ``target`` (board frame, metres), 640x480."""
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.vstack([x, y, z])
    K = np.array([[f, 0, 320.0], [0, f, 240.0], [0, 0, 1]])
    return K @ np.hstack([R, -(R @ eye)[:, None]])  # type: ignore[no-any-return]


def _box_silhouette(P: np.ndarray, center: np.ndarray, size: tuple[float, float], yaw: float, height: float):  # type: ignore[no-untyped-def]
    """(rows, cols) of the pixels an upright box covers: its surface sampled densely, projected."""
    g = np.linspace(-0.5, 0.5, 120)
    u, v, w = np.meshgrid(g, g, np.linspace(0, 1, 120), indexing="ij")
    on_surface = (np.abs(u) == 0.5) | (np.abs(v) == 0.5) | (w == 1)
    c, s = np.cos(yaw), np.sin(yaw)
    xl, yl = u[on_surface] * size[0], v[on_surface] * size[1]
    pts = np.column_stack([center[0] + c * xl - s * yl, center[1] + s * xl + c * yl, w[on_surface] * height])
    q = P @ np.hstack([pts, np.ones((pts.shape[0], 1))]).T
    pix = np.unique(np.round(q[:2] / q[2]).astype(int), axis=1)
    return pix[1], pix[0]


def test_the_footprint_is_where_the_rays_at_the_top_and_at_the_board_agree() -> None:
    """Whatever the viewing direction, the rays of an upright box's silhouette cut the top's plane
    and the board in sets whose intersection is the footprint, not the silhouette's shadow."""
    center = np.array([0.05, -0.03])
    for eye in (np.array([-0.35, 0.1, 0.55]), np.array([0.2, 0.4, 0.45]), np.array([0.03, -0.02, 0.7])):
        P = _camera(eye, np.array([0.05, -0.03, 0.0]))
        rows, cols = _box_silhouette(P, center, (0.06, 0.04), 0.4, 0.07)
        cells = footprint(P, rows, cols, 0.07)
        mid = (cells.min(axis=0) + cells.max(axis=0)) / 2
        assert np.linalg.norm(cells.mean(axis=0) - center) < 0.0015, eye
        assert np.linalg.norm(mid - center) < 0.003, eye
        # the area is the footprint's (24 cm^2), not the ground shadow of the whole silhouette
        assert abs(cells.shape[0] * 0.002**2 - 0.06 * 0.04) < 0.25 * 0.06 * 0.04, eye


def test_the_camera_is_fitted_from_the_organized_points() -> None:
    P = _camera(np.array([-0.3, 0.2, 0.6]), np.zeros(3))
    rng = np.random.default_rng(1)
    xyz = np.column_stack([rng.uniform(-0.1, 0.1, (400, 2)), rng.choice([0.0, 0.05], 400)])
    q = P @ np.hstack([xyz, np.ones((400, 1))]).T
    pix = (q[:2] / q[2]).T + rng.normal(0, 0.3, (400, 2))
    fitted = fit_camera(pix, xyz)
    assert fitted is not None
    px = np.array([100.0, 400.0]), np.array([50.0, 300.0])
    assert np.allclose(on_plane(fitted, *px, 0.03), on_plane(P, *px, 0.03), atol=0.001)
    assert fit_camera(pix, np.column_stack([xyz[:, :2], np.zeros(400)])) is None, "coplanar: not fixed"


def _dark_022():  # type: ignore[no-untyped-def]
    return bench_frame(BOARD, "dark", 22)  # bench_detector_real's dark-022


def test_a_black_object_in_the_fingers_stereo_shadow_is_found_from_its_silhouette() -> None:
    """A black cylinder almost wholly in the fingers' stereo shadow: depth saw two slivers of its
    side (each dropped as mixed pixels before, so the object was missed). From the colour
    silhouette and the slivers' height it is placed within a few millimetres, unconfident and
    saying that depth holes hide it."""
    f = _dark_022()
    truth = f.objects[0]
    assert truth.colour == "black" and f.visibility[0] > 0.95
    det = detect(f.points_base, f.board, rgb=f.rgb)
    assert len(det.objects) == 1, det.objects
    obj = det.objects[0]
    assert np.linalg.norm(np.array(obj.center[:2]) - truth.center[:2]) < 0.004
    assert abs(obj.extents[1] - truth.extents[1]) < 0.005
    assert obj.truncated == ("depth_holes",) and obj.confidence < 0.5
    assert obj.colour == "black"


def test_a_silhouette_running_out_of_the_image_places_nothing() -> None:
    """The same scene with a strip of the object's colour and without depth from it down to the
    image border (as the black fingers are): the silhouette is not bounded, so the slivers stay
    unplaced."""
    f = _dark_022()
    rgb, points = f.rgb.copy(), f.points_base.copy()
    T_cam_base = np.linalg.inv(f.T_base_cam)
    center_cam = T_cam_base[:3, :3] @ f.objects[0].center + T_cam_base[:3, 3]
    c, r = np.round(f.camera.project(center_cam[None, :])[0]).astype(int)
    box = f.rgb[r - 15 : r + 16, c - 15 : c + 16].reshape(-1, 3)
    dark = box[np.argsort(box.sum(axis=1))[: box.shape[0] // 5]]
    rgb[r:, c - 3 : c + 3] = np.round(dark.mean(axis=0))  # its shaded side
    points[r:, c - 3 : c + 3] = np.nan
    det = detect(points, f.board, rgb=rgb)
    assert not det.objects, det.objects


def test_a_footprint_covers_the_points_on_its_rotated_rectangle() -> None:
    from sofia_detector.objects.footprint import ObjectEstimate

    est = ObjectEstimate(np.array([0.1, 0.2]), 0.05, (0.06, 0.02), np.pi / 4, np.zeros(3), False, 100)
    along, across = np.array([1.0, 1.0]) / np.sqrt(2), np.array([-1.0, 1.0]) / np.sqrt(2)
    assert est.covers(est.center_xy + 0.029 * along) and est.covers(est.center_xy + 0.009 * across)
    assert not est.covers(est.center_xy + 0.031 * along) and not est.covers(est.center_xy + 0.011 * across)
