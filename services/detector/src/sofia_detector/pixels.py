"""Pixels of a mask on the pixel grid, in row-major order."""

from __future__ import annotations

import numpy as np


def where(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) (n,) intp of the True (non-zero) pixels of ``mask`` (h, w), in row-major order,
    as ``np.nonzero(mask)`` (several times faster on 2-D arrays)."""
    return divmod(np.flatnonzero(mask), mask.shape[1])  # type: ignore[no-any-return]


def masked_points(c: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(c[:, rows, cols], rows, cols)`` for ``rows, cols = where(mask)``: (3, n) coordinates of
    the pixels of ``mask`` (h, w) bool from ``c`` (3, h, w), and their (n,) rows and columns."""
    rows, cols = where(mask)
    return c[:, rows, cols], rows, cols
