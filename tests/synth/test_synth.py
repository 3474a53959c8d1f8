"""The synthetic scenes and calibration sessions agree with their ground truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sofia_replay import iter_clouds, iter_flange_poses, read_truth
from sofia_replay.synth import (
    DEFAULT_T_FLANGE_CAM,
    Camera,
    make_calibration_session,
    make_scene,
    render_scene,
    write_calibration_session,
    write_scene_set,
)
from sofia_replay.synth.scene import RED, WHITE
from sofia_schemas import Board
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_CAMERA_POINTS, TOPIC_POINTS
from sofia_schemas.transforms import apply, invert


@pytest.fixture(scope="module")
def board() -> Board:
    return Board.default()


@pytest.mark.parametrize("shape", ["box", "cylinder", "sphere"])
def test_object_points_lie_on_the_true_object(board: Board, shape: str) -> None:
    rng = np.random.default_rng(3)
    scene = make_scene(board, "one", rng, shape=shape)  # type: ignore[arg-type]
    frame = render_scene(scene, rng)
    obj = scene.objects[0]
    p = frame.points_base.reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    p_obj = apply(invert(obj.T_base_obj), p.astype(np.float64))
    half = obj.extents / 2
    inside = (np.abs(p_obj) <= half + 0.004).all(axis=1)
    assert inside.sum() > 300, f"only {inside.sum()} points on a {shape} of {obj.extents}"
    # the highest object points are at the object's top (within the depth noise)
    top = np.percentile(p_obj[inside, 2], 99.5)
    assert abs(top - half[2]) < 0.004
    # object points are coloured with the object's colour
    rgb = frame.render.rgb.reshape(-1, 3)[np.isfinite(frame.points_base.reshape(-1, 3)).all(axis=1)]
    colour_err = np.abs(rgb[inside].astype(int) - np.array(obj.colour)).max(axis=1)
    assert np.median(colour_err) < 15


def test_board_surface_matches_the_true_board_pose(board: Board) -> None:
    rng = np.random.default_rng(5)
    scene = make_scene(board, "empty", rng)
    frame = render_scene(scene, rng)
    p = frame.points_base.reshape(-1, 3).astype(np.float64)
    rgb = frame.render.rgb.reshape(-1, 3).astype(int)
    ok = np.isfinite(p).all(axis=1)
    is_field = ok & (
        (np.abs(rgb - np.array(RED)).max(axis=1) < 25) | (np.abs(rgb - np.array(WHITE)).max(axis=1) < 25)
    )
    p_board = apply(invert(scene.T_base_board), p[is_field])
    # field points lie on the true board surface, within the noise at ~0.75 m (sigma ~ 2.3 mm)
    assert abs(np.median(p_board[:, 2])) < 5e-4
    sigma = Camera().depth_sigma(np.median(apply(invert(frame.T_base_cam), p[is_field])[:, 2]))
    assert 0.6 * sigma < np.std(p_board[:, 2]) < 1.6 * sigma
    # the field a point falls in has the colour the board says
    rc = board.field_of_board_xy(p_board[:, :2])
    on = rc[:, 0] >= 0
    red_expected = np.array([board.is_allowed(r, c) for r, c in rc[on]])
    red_seen = np.abs(rgb[is_field][on] - np.array(RED)).max(axis=1) < 25
    assert np.mean(red_expected == red_seen) > 0.995


def test_board_is_perturbed_within_the_stated_bounds(board: Board) -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        T = make_scene(board, "empty", rng).T_base_board
        assert np.linalg.norm(T[:3, 3] - board.T_base_board[:3, 3]) <= 0.03 + 1e-9
        tilt = np.degrees(np.arccos(np.clip(T[2, 2], -1, 1)))
        assert tilt <= 3.0 + 1e-6


def test_scene_kinds_place_objects_on_the_right_fields(board: Board) -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        assert all(o.allowed for o in make_scene(board, "one", rng).objects)
        assert not any(o.allowed for o in make_scene(board, "nonred", rng).objects)
        assert make_scene(board, "empty", rng).objects == []
        two = make_scene(board, "two", rng).objects
        assert len(two) == 2 and two[0].field != two[1].field and two[0].allowed
    with pytest.raises(ValueError, match="scene kind"):
        make_scene(board, "three", rng)  # type: ignore[arg-type]


def test_calibration_frames_see_the_blob_where_the_truth_says(board: Board) -> None:
    rng = np.random.default_rng(7)
    session = make_calibration_session(4, rng)
    for f in session.frames:
        p_base = apply(f.T_base_flange @ session.T_flange_cam, f.p_cam_true)
        np.testing.assert_allclose(p_base, session.p_base_blob, atol=1e-9)
        dark = (f.rgb.astype(int).max(axis=-1) < 60) & np.isfinite(f.points_cam).all(axis=-1)
        assert dark.sum() > 50
        np.testing.assert_allclose(np.median(f.points_cam[dark], axis=0), f.p_cam_true, atol=0.003)


def test_scene_recording_round_trip(tmp_path: Path, board: Board) -> None:
    path = tmp_path / "scenes.mcap"
    truth = write_scene_set(path, "mixed", 3, seed=4, rate_hz=10.0)
    assert read_truth(path) == truth
    stamps = [f["stamp_ns"] for f in truth["frames"]]  # type: ignore[index]
    base = list(iter_clouds(path, topics=[TOPIC_POINTS]))
    cam = list(iter_clouds(path, topics=[TOPIC_CAMERA_POINTS]))
    poses = list(iter_flange_poses(path))
    assert [c.stamp_ns for _, _, c in base] == stamps == [c.stamp_ns for _, _, c in cam]
    assert [t for t, _ in poses] == stamps
    # the camera-frame cloud mapped with the recorded flange pose and T_flange_cam is the base cloud
    (_, _, cb), (_, _, cc), (_, pose) = base[0], cam[0], poses[0]
    T_base_cam = pose.matrix() @ np.array(truth["T_flange_cam"])
    mapped = apply(T_base_cam, cc.xyz().reshape(-1, 3).astype(np.float64))
    ref = cb.xyz().reshape(-1, 3)
    ok = np.isfinite(ref).all(axis=1)
    assert np.isfinite(mapped[ok]).all() and np.abs(mapped[ok] - ref[ok]).max() < 1e-4
    assert cb.frame_id == board.frame_id and cb.shape == (480, 640) and cb.rgb() is not None
    assert np.allclose(truth["T_flange_cam"], DEFAULT_T_FLANGE_CAM)


def test_calibration_recording_has_still_and_moving_poses(tmp_path: Path) -> None:
    path = tmp_path / "calib.mcap"
    session = write_calibration_session(path, 3, seed=1, clouds=False)
    truth = read_truth(path)
    assert truth is not None and len(truth["frames"]) == 3
    blobs = [s for s in iter_clouds(path, topics=[TOPIC_BLOB])]
    assert blobs == []  # blobs are PointStamped, not clouds
    poses = list(iter_flange_poses(path))
    stamps = {f.stamp_ns for f in session.frames}
    at_frames = [p for t, p in poses if t in stamps]
    assert len(at_frames) == 3
    for f, (_, p) in zip(session.frames, [(t, p) for t, p in poses if t in stamps], strict=True):
        np.testing.assert_allclose(p.matrix(), f.T_base_flange, atol=1e-6)
    assert len(poses) == 3 * 3 + 2 * 8  # still before/at/after each frame, 8 moving poses between
