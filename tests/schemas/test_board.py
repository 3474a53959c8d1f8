"""The board model: files, the field-centre formula, the field of a point, validation."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from sofia_schemas import Board

ISSUE_BOARD: dict[str, Any] = {
    "frame_id": "panda_link0",
    "center": [0.5, 0.0],
    "surface_z": 0.0,
    "yaw": 0.0,
    "rows": 3,
    "cols": 4,
    "field_size": [0.15, 0.15],
    "allowed": [[0, 0], [0, 2], [1, 1], [1, 3], [2, 0], [2, 2]],
}


def test_default_board_is_the_lab_board() -> None:
    assert json.loads(Board.default().model_dump_json()) == ISSUE_BOARD


@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".json"])
def test_from_file(tmp_path: Path, suffix: str) -> None:
    data = dict(ISSUE_BOARD, yaw=0.3, center=[0.45, -0.1], surface_z=0.02)
    path = tmp_path / f"board{suffix}"
    path.write_text(json.dumps(data) if suffix == ".json" else yaml.safe_dump(data))
    board = Board.from_file(path)
    assert board.yaw == 0.3 and board.center == (0.45, -0.1) and board.surface_z == 0.02
    assert board.allowed == tuple(tuple(a) for a in ISSUE_BOARD["allowed"])


def test_yaml_round_trip(tmp_path: Path) -> None:
    board = Board(yaw=-0.7, rows=2, cols=5, allowed=((1, 4),))
    path = tmp_path / "b.yaml"
    path.write_text(board.to_yaml())
    assert Board.from_file(path) == board


@settings(max_examples=60, deadline=None)
@given(
    cx=st.floats(-1, 1), cy=st.floats(-1, 1), z=st.floats(-0.2, 0.5), yaw=st.floats(-np.pi, np.pi),
    rows=st.integers(1, 6), cols=st.integers(1, 6), fx=st.floats(0.02, 0.3), fy=st.floats(0.02, 0.3),
)  # fmt: skip
def test_field_centre_formula(
    cx: float, cy: float, z: float, yaw: float, rows: int, cols: int, fx: float, fy: float
) -> None:
    """centre(r, c) = center + Rz(yaw) @ [(r - (rows-1)/2) fx, (c - (cols-1)/2) fy], at surface_z."""
    board = Board(
        center=(cx, cy), surface_z=z, yaw=yaw, rows=rows, cols=cols, field_size=(fx, fy), allowed=()
    )
    Rz = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    for r in range(rows):
        for c in range(cols):
            want_xy = np.array([cx, cy]) + Rz @ [(r - (rows - 1) / 2) * fx, (c - (cols - 1) / 2) * fy]
            np.testing.assert_allclose(board.field_center_base(r, c), [*want_xy, z], atol=1e-12)
    # and back: each centre falls in its own field
    centres_base = np.array([board.field_center_base(r, c) for r in range(rows) for c in range(cols)])
    rc = board.field_of_board_xy(board.base_to_board(centres_base)[:, :2])
    np.testing.assert_array_equal(rc, [[r, c] for r in range(rows) for c in range(cols)])


def test_lab_board_numbers() -> None:
    board = Board.default()
    np.testing.assert_allclose(board.field_center_base(0, 0), [0.5 - 0.15, -0.225, 0.0])
    np.testing.assert_allclose(board.field_center_base(2, 3), [0.5 + 0.15, 0.225, 0.0])
    assert board.is_allowed(1, 1) and not board.is_allowed(1, 2)
    assert board.extent == pytest.approx((0.45, 0.6))


def test_off_board_points_are_minus_one() -> None:
    board = Board.default()
    rc = board.field_of_board_xy(np.array([[0.3, 0.0], [0.0, -0.31], [0.0, 0.0]]))
    np.testing.assert_array_equal(rc, [[-1, -1], [-1, -1], [1, 2]])


@pytest.mark.parametrize(
    "change,message",
    [
        ({"allowed": [[3, 0]]}, r"allowed field \(3, 0\) is outside the 3x4 board"),
        ({"field_size": [0.15, -0.1]}, r"field_size must be positive, got \(0.15, -0.1\)"),
        ({"center": [float("nan"), 0.0]}, "must be finite"),
        ({"rows": 0}, "rows"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_validation_errors(change: dict[str, object], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        Board.model_validate(dict(ISSUE_BOARD, **change))


def test_file_that_is_not_a_mapping(tmp_path: Path) -> None:
    path = tmp_path / "board.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="expected a mapping of board fields, got list"):
        Board.from_file(path)


def test_field_outside_board() -> None:
    with pytest.raises(ValueError, match=r"field \(0, 4\) is outside the 3x4 board"):
        Board.default().field_center_base(0, 4)


def test_field_at_is_field_of_board_xy_for_one_point() -> None:
    """The scalar lookup the detector uses per object gives the vectorised lookup's field, on the
    fields' edges and a float's step either side of them too; None where that gives -1."""
    board = Board.default()
    fx, fy = board.field_size
    rows, cols = np.meshgrid(np.arange(board.rows + 1), np.arange(board.cols + 1), indexing="ij")
    edges = np.stack([(rows - board.rows / 2) * fx, (cols - board.cols / 2) * fy], axis=-1).reshape(-1, 2)
    xy = np.concatenate([
        np.random.default_rng(5).uniform(-0.6, 0.6, (5000, 2)), edges,
        np.nextafter(edges, -np.inf), np.nextafter(edges, np.inf),
    ])  # fmt: skip
    vectorised = board.field_of_board_xy(xy)
    scalar = [board.field_at(float(x), float(y)) for x, y in xy]
    assert [tuple(rc) if rc[0] >= 0 else None for rc in vectorised.tolist()] == scalar
    assert any(rc is None for rc in scalar) and any(rc is not None for rc in scalar)


def test_board_pose_is_shared_read_only_and_follows_the_board() -> None:
    """The pose is computed once per board geometry and handed out read-only: no caller can change
    another's; a board moved or turned gets its own."""
    board = Board.default()
    T = board.T_base_board
    assert T is Board.default().T_base_board and not T.flags.writeable
    assert not board.R_base_board.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        T[0, 3] = 1.0
    turned = board.model_copy(update={"yaw": 0.3, "center": (0.6, -0.1), "surface_z": 0.02})
    c, s = np.cos(0.3), np.sin(0.3)
    expected = np.array([[c, -s, 0, 0.6], [s, c, 0, -0.1], [0, 0, 1, 0.02], [0, 0, 0, 1]])
    np.testing.assert_array_equal(turned.T_base_board, expected)
    np.testing.assert_array_equal(turned.R_base_board, expected[:3, :3])
    assert board.T_base_board[0, 3] == board.center[0]
