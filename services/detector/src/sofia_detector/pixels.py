"""Small operations on pixel grids and samples, without the per-call overhead of their general forms.

``scipy.ndimage`` filters and ``np.median`` cost tens of microseconds per call whatever the size of
their input; the detector calls them on small windows many times per cloud. These give the same
results (square dilation and erosion ignore pixels outside the image, like the filters' default
``reflect`` border) with a few slice operations.
"""

from __future__ import annotations

import numpy as np

from .kernels import jit


def where(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) (n,) intp of the True (non-zero) pixels of ``mask`` (h, w), in row-major order,
    as ``np.nonzero(mask)`` (several times faster on 2-D arrays)."""
    return divmod(np.flatnonzero(mask), mask.shape[1])  # type: ignore[no-any-return]


@jit
def masked_points(c: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(c[:, rows, cols], rows, cols)`` for ``rows, cols = where(mask)`` in one pass: (3, n)
    coordinates of the pixels of ``mask`` (h, w) bool from ``c`` (3, h, w), and their (n,) int64
    rows and columns, in row-major order."""
    h, w = mask.shape
    n = 0
    for r in range(h):
        for q in range(w):
            n += mask[r, q]
    out = np.empty((3, n), dtype=c.dtype)
    rows, cols = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    k = 0
    for r in range(h):
        for q in range(w):
            if mask[r, q]:
                out[0, k], out[1, k], out[2, k] = c[0, r, q], c[1, r, q], c[2, r, q]
                rows[k], cols[k] = r, q
                k += 1
    return out, rows, cols


def grow(mask: np.ndarray, size: int) -> np.ndarray:
    """(h, w) bool ``mask`` dilated by a ``size`` x ``size`` square (``size`` odd)."""
    k = size // 2
    rows = mask.copy()
    for d in range(1, k + 1):
        rows[d:] |= mask[:-d]
        rows[:-d] |= mask[d:]
    out = rows.copy()
    for d in range(1, k + 1):
        out[:, d:] |= rows[:, :-d]
        out[:, :-d] |= rows[:, d:]
    return out


@jit
def grow_jit(mask: np.ndarray, size: int) -> np.ndarray:
    """:func:`grow`, callable from compiled code: (h, w) bool ``mask`` dilated by a ``size`` x
    ``size`` square (``size`` odd), along the columns then the rows, as :func:`grow` does."""
    k = size // 2
    h, w = mask.shape
    rows = mask.copy()
    for d in range(1, k + 1):
        for r in range(d, h):
            for c in range(w):
                rows[r, c] |= mask[r - d, c]
        for r in range(h - d):
            for c in range(w):
                rows[r, c] |= mask[r + d, c]
    out = rows.copy()
    for r in range(h):
        for d in range(1, k + 1):
            for c in range(d, w):
                out[r, c] |= rows[r, c - d]
            for c in range(w - d):
                out[r, c] |= rows[r, c + d]
    return out


def shrink(mask: np.ndarray, size: int) -> np.ndarray:
    """(h, w) bool ``mask`` eroded by a ``size`` x ``size`` square (``size`` odd); pixels outside
    the image do not erode it."""
    return ~grow(~mask, size)


def median(x: np.ndarray) -> np.ndarray:
    """Median along the first axis of x (n, ...) with n >= 1, as ``np.median(x, axis=0)`` (float
    input keeps its dtype, integers give float64; (n, 3) uint8 colours are counted)."""
    if x.dtype == np.uint8 and x.ndim == 2 and x.shape[1] == 3:
        return _median_u8(np.ascontiguousarray(x))  # type: ignore[no-any-return]
    if x.dtype.kind != "f":
        x = x.astype(np.float64)
    n = x.shape[0]
    h = n // 2
    if n % 2:
        return np.partition(x, h, axis=0)[h]  # type: ignore[no-any-return]
    part = np.partition(x, (h - 1, h), axis=0)
    return (part[h - 1] + part[h]) / 2  # type: ignore[no-any-return]


@jit
def _median_u8(px: np.ndarray) -> np.ndarray:
    """(3,) float64 median of each channel of (n, 3) uint8 colours (n >= 1), by counting."""
    counts = np.zeros((3, 256), dtype=np.int64)
    for i in range(px.shape[0]):
        for ch in range(3):
            counts[ch, px[i, ch]] += 1
    return _counted_median(counts, px.shape[0])


@jit
def median_u8_at(rgb: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``median(rgb[rows, cols])`` without gathering the colours: (3,) float64 median of each
    channel of the pixels (rows, cols) (n,) (n >= 1) of ``rgb`` (h, w, 3) uint8 (any strides)."""
    counts = np.zeros((3, 256), dtype=np.int64)
    for i in range(rows.size):
        for ch in range(3):
            counts[ch, rgb[rows[i], cols[i], ch]] += 1
    return _counted_median(counts, rows.size)


@jit
def _counted_median(counts: np.ndarray, n: int) -> np.ndarray:
    """(3,) float64 median of each channel from its value counts (3, 256) of n colours."""
    out = np.empty(3)
    lo_rank, hi_rank = (n - 1) // 2, n // 2  # the middle one or two, 0-based
    for ch in range(3):
        seen, lo, hi = 0, -1, -1
        for v in range(256):
            seen += counts[ch, v]
            if lo < 0 and seen > lo_rank:
                lo = v
            if seen > hi_rank:
                hi = v
                break
        out[ch] = (lo + hi) / 2
    return out
