"""The wooden board of 12 fields the objects lie on."""

from __future__ import annotations

import hashlib
import json
import math
import os
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from .files import load_json_or_yaml
from .frames import BASE_FRAME

DEFAULT_BOARD_FILE = "default_board.yaml"
BOARD_ENV = "SOFIA_BOARD"  # path of the board every command and service uses without --board
CONFIG_BOARD = Path("config") / "board.yaml"  # the lab's board, relative to the working directory
BOARD_HELP = (
    "board YAML/JSON (default: $SOFIA_BOARD, else config/board.yaml when present, else the package's)"
)


def default_board_path() -> Path | None:
    """The board file of every command and service started without ``--board``: ``$SOFIA_BOARD``,
    else ``config/board.yaml`` in the working directory when it exists, else None (the package's
    board, :meth:`Board.default`). ``sofia up``, ``sofia detect``, ``detector serve``, ``viz serve``
    and the demo all resolve it here."""
    env = os.environ.get(BOARD_ENV, "").strip()
    if env:
        return Path(env)
    return CONFIG_BOARD if CONFIG_BOARD.is_file() else None


@lru_cache(maxsize=64)
def _board_pose(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    """(4, 4) read-only pose of a board frame at ``(x, y, z)`` turned ``yaw`` about the base z axis.
    Cached: the detector maps every cloud with it."""
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.array([[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]])
    T.flags.writeable = False
    return T


class Board(BaseModel):
    """Board geometry in the robot base frame.

    Field ``(r, c)`` has its centre at
    ``center + Rz(yaw) @ [(r - (rows-1)/2) * fx, (c - (cols-1)/2) * fy]`` and its top surface at
    ``surface_z``. ``allowed`` lists the red fields as ``(row, col)``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    frame_id: str = BASE_FRAME
    center: tuple[float, float] = (0.5, 0.0)
    surface_z: float = 0.0
    yaw: float = 0.0
    rows: int = Field(3, ge=1)
    cols: int = Field(4, ge=1)
    field_size: tuple[float, float] = (0.15, 0.15)
    allowed: tuple[tuple[int, int], ...] = ((0, 0), (0, 2), (1, 1), (1, 3), (2, 0), (2, 2))

    @field_validator("center", "field_size")
    @classmethod
    def _finite(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not np.all(np.isfinite(v)):
            raise ValueError(f"must be finite, got {v}")
        return v

    @field_validator("field_size")
    @classmethod
    def _positive(cls, v: tuple[float, float]) -> tuple[float, float]:
        if min(v) <= 0:
            raise ValueError(f"field_size must be positive, got {v}")
        return v

    @model_validator(mode="after")
    def _allowed_in_range(self) -> Board:
        for r, c in self.allowed:
            if not (0 <= r < self.rows and 0 <= c < self.cols):
                raise ValueError(f"allowed field {(r, c)} is outside the {self.rows}x{self.cols} board")
        return self

    # --- construction -----------------------------------------------------
    @classmethod
    def from_file(cls, path: str | Path) -> Board:
        """Read a board from a YAML (``.yaml``/``.yml``) or JSON file."""
        data = load_json_or_yaml(path)
        if not isinstance(data, dict):
            raise ValueError(f"{path}: expected a mapping of board fields, got {type(data).__name__}")
        return cls.model_validate(data)

    @classmethod
    def load(cls, path: str | Path | None = None) -> Board:
        """The board of ``path``, or without one the configured default (:func:`default_board_path`)."""
        chosen = path or default_board_path()
        return cls.from_file(chosen) if chosen else cls.default()

    @property
    def digest(self) -> str:
        """12 hex digits naming this geometry (sha256 of its JSON): services report it in their
        status, so two processes can be checked to use the same board."""
        return hashlib.sha256(self.model_dump_json().encode()).hexdigest()[:12]

    @classmethod
    def default(cls) -> Board:
        """The board shipped with the package (``sofia_schemas/data/default_board.yaml``)."""
        text = resources.files("sofia_schemas").joinpath("data", DEFAULT_BOARD_FILE).read_text()
        return cls.model_validate(yaml.safe_load(text))

    def to_yaml(self) -> str:
        data = json.loads(self.model_dump_json())
        return yaml.safe_dump(data, sort_keys=False)

    # --- geometry ---------------------------------------------------------
    @property
    def R_base_board(self) -> np.ndarray:
        """(3, 3) rotation of the board frame (x along rows, y along cols) in the base frame
        (read-only)."""
        return self.T_base_board[:3, :3]

    @property
    def T_base_board(self) -> np.ndarray:
        """(4, 4) pose of the board frame: origin at the board centre on the top surface
        (read-only)."""
        return _board_pose(self.center[0], self.center[1], self.surface_z, self.yaw)

    @property
    def extent(self) -> tuple[float, float]:
        """Board size along its own x and y axes, metres."""
        return (self.rows * self.field_size[0], self.cols * self.field_size[1])

    def field_centers_board(self) -> np.ndarray:
        """(rows, cols, 2) field centres in the board frame (x, y), metres."""
        r = (np.arange(self.rows) - (self.rows - 1) / 2) * self.field_size[0]
        c = (np.arange(self.cols) - (self.cols - 1) / 2) * self.field_size[1]
        rr, cc = np.meshgrid(r, c, indexing="ij")
        return np.stack([rr, cc], axis=-1)

    def field_center_base(self, row: int, col: int) -> np.ndarray:
        """(3,) centre of field ``(row, col)`` on the board surface, base frame, metres."""
        if not (0 <= row < self.rows and 0 <= col < self.cols):
            raise ValueError(f"field {(row, col)} is outside the {self.rows}x{self.cols} board")
        xy_board = self.field_centers_board()[row, col]
        p_board = np.array([xy_board[0], xy_board[1], 0.0])
        return self.T_base_board[:3, :3] @ p_board + self.T_base_board[:3, 3]

    def field_of_board_xy(self, xy_board: np.ndarray) -> np.ndarray:
        """Field index of board-frame points.

        xy_board: (n, 2) float, board frame, metres.
        Returns (n, 2) int ``(row, col)``; ``-1`` where the point is off the board.
        """
        xy_board = np.asarray(xy_board, dtype=np.float64).reshape(-1, 2)
        fx, fy = self.field_size
        rc = np.floor(xy_board / np.array([fx, fy]) + np.array([self.rows / 2, self.cols / 2])).astype(
            np.int64
        )
        off = (rc[:, 0] < 0) | (rc[:, 0] >= self.rows) | (rc[:, 1] < 0) | (rc[:, 1] >= self.cols)
        rc[off] = -1
        return rc

    def field_at(self, x_board: float, y_board: float) -> tuple[int, int] | None:
        """Field ``(row, col)`` of one board-frame point (metres), None off the board: the scalar
        :meth:`field_of_board_xy` (the same arithmetic, without numpy's per-call overhead)."""
        fx, fy = self.field_size
        row, col = math.floor(x_board / fx + self.rows / 2), math.floor(y_board / fy + self.cols / 2)
        return (row, col) if 0 <= row < self.rows and 0 <= col < self.cols else None

    def is_allowed(self, row: int, col: int) -> bool:
        """True when ``(row, col)`` is a red field."""
        return (int(row), int(col)) in {tuple(a) for a in self.allowed}

    def base_to_board(self, points_base: np.ndarray) -> np.ndarray:
        """Map base-frame points into the board frame.

        points_base: (..., 3) float, base frame, metres. Returns (..., 3), board frame.
        """
        T = self.T_base_board
        return (np.asarray(points_base) - T[:3, 3]) @ T[:3, :3]
