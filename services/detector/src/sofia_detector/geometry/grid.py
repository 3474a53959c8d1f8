"""Connected components and square morphology of pixel grids, by OpenCV (and SciPy's hole filling).

OpenCV's calls cost a few microseconds on the detector's small grids (the coarse seeds, each
object's window, its top, the board's outline), where ``scipy.ndimage``'s labelling and filters
cost 20-150 us each, mostly setting up. Pixels outside the image neither grow nor erode a mask.
OpenCV runs in the calling thread: its thread pool's start and hand-over cost more than these
grids' work (connected components of a 120 x 160 grid: ~0.4 ms with two threads on a loaded
machine, ~20 us in one), and its threads would take the core the service's other work needs.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage

from .compiled import jit

cv2.setNumThreads(1)


def _u8(mask: np.ndarray) -> np.ndarray:
    """(h, w) uint8 0/1 of a 2-D mask (no copy when it is C-contiguous bool)."""
    return np.ascontiguousarray(mask, dtype=np.bool_).view(np.uint8)


def _square(size: int) -> np.ndarray:
    return np.ones((size, size), dtype=np.uint8)


def label8(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """(labels (h, w) int32, n): the 8-connected components of ``mask`` (h, w) bool, numbered 1..n;
    0 off the mask."""
    if mask.size == 0:
        return np.zeros(mask.shape, dtype=np.int32), 0
    n, labels = cv2.connectedComponents(_u8(mask), connectivity=8, ltype=cv2.CV_32S)
    return labels, n - 1


def label_sizes(mask: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """:func:`label8` of ``mask`` (h, w) bool with each label's pixel count: (labels, n, sizes
    (n + 1,) int of labels 0..n, 0 the pixels off the mask). (OpenCV's labelling with statistics
    costs 3-4 times its labelling alone on these grids; the counts are one ``bincount``.)"""
    labels, n = label8(mask)
    return labels, n, np.bincount(labels.ravel(), minlength=n + 1)


def largest_component(mask: np.ndarray) -> np.ndarray:
    """(h, w) bool: the largest 8-connected component of ``mask`` (h, w) bool (the first of equal
    ones); the empty mask when ``mask`` is empty."""
    labels, n, sizes = label_sizes(mask)
    if n == 0:
        return np.zeros(mask.shape, dtype=bool)
    return labels == 1 + int(np.argmax(sizes[1:]))  # type: ignore[no-any-return]


def max_filter(a: np.ndarray, size: int) -> np.ndarray:
    """(h, w) int32: the largest value of ``a`` (h, w) int >= 0 (below 2**24: labels) within a
    ``size`` x ``size`` square (odd) around each pixel."""
    out = cv2.dilate(np.ascontiguousarray(a, dtype=np.float32), _square(size))
    return out.astype(np.int32)  # type: ignore[no-any-return]


def grow(mask: np.ndarray, size: int) -> np.ndarray:
    """(h, w) bool ``mask`` dilated by a ``size`` x ``size`` square (``size`` odd)."""
    return cv2.dilate(_u8(mask), _square(size)).view(np.bool_)  # type: ignore[no-any-return]


def shrink(mask: np.ndarray, size: int) -> np.ndarray:
    """(h, w) bool ``mask`` eroded by a ``size`` x ``size`` square (``size`` odd); pixels outside
    the image do not erode it."""
    return cv2.erode(_u8(mask), _square(size)).view(np.bool_)  # type: ignore[no-any-return]


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """(h, w) bool ``mask`` (h, w) with its holes filled: the background not 4-connected to the
    image border."""
    return ndimage.binary_fill_holes(mask)  # type: ignore[no-any-return]


def grid_boundary(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row/column extremes of a 2-D mask: every vertex of its convex hull is among them.

    Returns (rows (k,), cols (k,)) int indices of the first and last True cell of every non-empty
    row, then of every non-empty column.
    """
    rows, cols = where(mask)
    at = boundary_points(rows, cols, *mask.shape)
    return rows[at], cols[at]


@jit
def boundary_points(
    rows: np.ndarray, cols: np.ndarray, h: int, w: int, subset: np.ndarray | None = None
) -> np.ndarray:
    """:func:`grid_boundary` of pixels given by index: (k,) indices into rows, cols (n,) (distinct
    pixels of an (h, w) grid) of the first and last pixel of every non-empty row, then of every
    non-empty column, in :func:`grid_boundary`'s order. subset: (n,) bool, only those pixels
    (the indices still into rows, cols: nothing is gathered)."""
    first_c, last_c = np.full(h, -1), np.full(h, -1)  # the point at the row's first, last column
    first_r, last_r = np.full(w, -1), np.full(w, -1)
    for i in range(rows.size):
        if subset is not None and not subset[i]:
            continue
        r, c = rows[i], cols[i]
        if first_c[r] < 0 or c < cols[first_c[r]]:
            first_c[r] = i
        if last_c[r] < 0 or c > cols[last_c[r]]:
            last_c[r] = i
        if first_r[c] < 0 or r < rows[first_r[c]]:
            first_r[c] = i
        if last_r[c] < 0 or r > rows[last_r[c]]:
            last_r[c] = i
    by_row, by_col = first_c[first_c >= 0], first_r[first_r >= 0]
    return np.concatenate((by_row, last_c[last_c >= 0], by_col, last_r[last_r >= 0]))


def where(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) (n,) intp of the True (non-zero) pixels of ``mask`` (h, w), in row-major order,
    as ``np.nonzero(mask)`` (several times faster on 2-D arrays)."""
    return divmod(np.flatnonzero(mask), mask.shape[1])  # type: ignore[no-any-return]


def masked_points(c: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(c[:, rows, cols], rows, cols)`` for ``rows, cols = where(mask)``: (3, n) coordinates of
    the pixels of ``mask`` (h, w) bool from ``c`` (3, h, w), and their (n,) rows and columns."""
    rows, cols = where(mask)
    return c[:, rows, cols], rows, cols
