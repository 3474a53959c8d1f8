"""The points of one object."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.grid import boundary_points
from ..geometry.rect import hull


@dataclass(frozen=True)
class ObjectPoints:
    """One object: b (3, n) float32 board-frame coordinates (z = height), metres. Organized clouds
    also give each point's pixel (rows, cols) in a window of ``shape`` and the window around them;
    unorganized clouds with colours, each point's colour."""

    b: np.ndarray
    rows: np.ndarray | None = None
    cols: np.ndarray | None = None
    shape: tuple[int, int] = (0, 0)
    origin: tuple[int, int] = (0, 0)  # (row, col) of the window in the image
    image_shape: tuple[int, int] = (0, 0)
    window: np.ndarray | None = None  # (3, *shape) float32 board-frame coordinates of the window
    rgb: np.ndarray | None = None  # (*shape, 3) uint8 colours of the window
    point_rgb: np.ndarray | None = None  # (n, 3) uint8 colours of the points (unorganized clouds)

    def boundary_xy(self, subset: np.ndarray | None = None) -> np.ndarray:
        """(k, 2) xy of ``subset`` ((n,) bool, default all) including their hull's vertices."""
        if self.rows is None or self.cols is None:
            return hull((self.b if subset is None else self.b[:, subset])[:2].T)
        return self.b[:2, boundary_points(self.rows, self.cols, self.shape, subset)].T
