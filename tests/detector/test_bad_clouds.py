"""Clouds that are not a board scene: a clear result or a clear error, never a crash."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from sofia_detector import BadCloud, detect
from sofia_schemas import Board

BOARD = Board.default()
LINE = np.column_stack(  # points along one line on the board's surface
    [
        np.linspace(-0.15, 0.15, 500) + BOARD.center[0],
        np.full(500, BOARD.center[1]),
        np.full(500, BOARD.surface_z),
    ]
)


@pytest.mark.parametrize(
    ("name", "points"),
    [
        ("nan-only organized", np.full((480, 640, 3), np.nan, np.float32)),
        ("nan-only unorganized", np.full((1000, 3), np.nan)),
        ("empty", np.zeros((0, 3))),
        ("empty organized", np.zeros((0, 640, 3), np.float32)),
        ("one point on the board", np.array([[0.5, 0.0, 0.0]])),
        ("huge coordinates", np.full((500, 3), 1e30)),
        ("float64 max", np.full((50, 3), np.finfo(np.float64).max)),
        ("inf", np.full((48, 64, 3), np.inf, np.float32)),
        ("-inf and nan mix", np.stack([np.full(300, -np.inf), np.full(300, np.nan), np.zeros(300)], axis=1)),
        ("integers", np.zeros((10, 3), np.int64)),
        ("far away", np.random.default_rng(0).normal(100.0, 1.0, (2000, 3))),
        ("a line on the board", LINE),  # no plane through it (the plane fit raised LinAlgError)
    ],
)
def test_no_board_is_a_clear_result(name: str, points: np.ndarray) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning leaks from overflow or NaN
        det = detect(points, BOARD)
    assert det.status == "no_board", name
    assert det.objects == []
    assert det.detail, "a no_board result says why"


def test_flat_board_alone_is_no_object() -> None:
    rng = np.random.default_rng(0)
    xy = rng.uniform([-0.2, -0.28], [0.2, 0.28], (20000, 2)) + BOARD.center
    pts = np.column_stack([xy, rng.normal(0.0, 0.002, 20000)])
    det = detect(pts, BOARD)
    assert det.status == "no_object" and det.objects == []


def test_huge_values_mixed_into_a_scene_are_ignored(scenes) -> None:
    pts = scenes["box"].points_base.copy()
    pts[::7, ::5] = 3e38
    pts[1::9, ::3] = -np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        det = detect(pts, BOARD)
    assert len(det.objects) == 1
    assert np.linalg.norm(np.array(det.objects[0].center) - scenes["box"].objects[0].center) < 0.005


@pytest.mark.parametrize(
    ("points", "needle"),
    [
        (np.zeros(3), "got (3,)"),
        (np.zeros((5, 4)), "got (5, 4)"),
        (np.zeros((2, 2, 2, 3)), "got (2, 2, 2, 3)"),
        (np.array([["a", "b", "c"]]), "dtype <U1"),
        (np.zeros((4, 3), complex), "dtype complex128"),
        ([[1.0, 2.0], [3.0]], "cannot be read as an array"),
    ],
)
def test_not_a_cloud_raises_bad_cloud(points: object, needle: str) -> None:
    with pytest.raises(BadCloud, match="bad point cloud") as e:
        detect(points, BOARD)
    assert needle in str(e.value)
    assert isinstance(e.value, ValueError)
