"""Generate a board and a box from known poses, recover them (property-based)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sofia_detector import detect
from sofia_detector.geometry.rect import min_area_rect
from sofia_schemas import Board

BOARD = Board.default()


def _top_down_scene(
    tilt: tuple[float, float], offset: tuple[float, float, float], size: tuple[float, float, float],
    xy: tuple[float, float], yaw: float,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Organized (H, W, 3) cloud seen straight from above: a tilted board and a box standing on it.

    Returns the cloud (base frame) and the box's bounding-box centre (3,), base frame.
    """
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xy", tilt).as_matrix()
    t = np.array([BOARD.center[0] + offset[0], BOARD.center[1] + offset[1], offset[2]])
    u, v = np.meshgrid(np.arange(-0.26, 0.26, 0.0015), np.arange(-0.34, 0.34, 0.0015), indexing="ij")
    c, s = np.cos(yaw), np.sin(yaw)
    du, dv = u - xy[0], v - xy[1]
    inside = (np.abs(c * du + s * dv) <= size[0] / 2) & (np.abs(-s * du + c * dv) <= size[1] / 2)
    w = np.where(inside, size[2], 0.0)
    p_board = np.stack([u, v, w], axis=-1)
    p_board[(np.abs(u) > 0.245) | (np.abs(v) > 0.32)] = np.nan  # board edge
    points = (p_board @ R.T + t).astype(np.float32)
    center = R @ np.array([xy[0], xy[1], size[2] / 2]) + t
    return points, center


@settings(max_examples=15, deadline=None)
@given(
    tilt=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)),
    offset=st.tuples(st.floats(-0.02, 0.02), st.floats(-0.02, 0.02), st.floats(-0.01, 0.01)),
    size=st.tuples(st.floats(0.03, 0.1), st.floats(0.03, 0.1), st.floats(0.03, 0.1)),
    field=st.sampled_from([(r, c) for r in range(3) for c in range(4)]),
    yaw=st.floats(-np.pi, np.pi),
)
def test_box_on_tilted_offset_board_is_recovered(tilt, offset, size, field, yaw) -> None:  # type: ignore[no-untyped-def]
    xy = BOARD.field_centers_board()[field]
    points, center = _top_down_scene(tilt, offset, size, (float(xy[0]), float(xy[1])), yaw)
    det = detect(points, BOARD)
    assert len(det.objects) == 1
    obj = det.objects[0]
    assert np.linalg.norm(np.array(obj.center) - center) < 0.003
    assert obj.field == field and obj.allowed == BOARD.is_allowed(*field)
    assert sorted(obj.extents[:2]) == pytest.approx(sorted(size[:2]), abs=0.004)


@settings(max_examples=30, deadline=None)
@given(
    w=st.floats(0.01, 1.0),
    h=st.floats(0.01, 1.0),
    yaw=st.floats(-np.pi, np.pi),
    cx=st.floats(-1, 1),
    cy=st.floats(-1, 1),
)
def test_min_area_rect_of_a_rectangle(w: float, h: float, yaw: float, cx: float, cy: float) -> None:
    g = np.stack(np.meshgrid(np.linspace(-w / 2, w / 2, 7), np.linspace(-h / 2, h / 2, 9)), -1).reshape(-1, 2)
    c, s = np.cos(yaw), np.sin(yaw)
    xy = g @ np.array([[c, s], [-s, c]]) + (cx, cy)
    rect = min_area_rect(xy)
    assert np.allclose(rect.center, (cx, cy), atol=1e-6)  # OpenCV's float32 about the first point
    assert sorted(rect.size) == pytest.approx(sorted((w, h)), rel=1e-5)
