"""Means of float32 rows, compiled, equal to numpy's to the bit.

The detector's centroids and centres are means over an object's points, and its detections are
compared byte for byte from release to release. numpy sums a row whose elements lie closer together
than the rows do pairwise (blocks of 8 partial sums up to 128 elements, halves beyond), and a sum
that casts float32 to float64 buffer by buffer (:func:`numpy.getbufsize` elements), adding each
buffer's pairwise sum in turn; rows laid out the other way (gathered pixels: the rows interleaved)
it sums element after element. These do the same in one compiled call, without ``np.mean``'s
per-call cost on the detector's small arrays.
"""

from __future__ import annotations

import numpy as np

from .kernels import jit

BLOCK = 128  # numpy's pairwise-summation block (PW_BLOCKSIZE)


@jit
def _sequential(a: np.ndarray, lo: int, n: int, r: np.ndarray) -> float:
    """``a[lo] + a[lo + 1] + ...`` (n elements of 1-D ``a``) in turn, from 0 in the dtype of ``r``."""
    r[0] = 0
    res = r[0]
    for i in range(n):
        res += a[lo + i]
    return res


@jit
def _interleaved(x: np.ndarray) -> bool:
    """Whether numpy sums the rows of ``x`` (k, n) element after element: k > 1 rows lying closer
    together than a row's elements."""
    return x.shape[0] > 1 and x.strides[1] > x.strides[0]  # type: ignore[no-any-return]


@jit
def _block(a: np.ndarray, lo: int, n: int, r: np.ndarray) -> float:
    """numpy's sum of ``a[lo:lo + n]`` (1-D, n <= :data:`BLOCK`), accumulated in the dtype of ``r``
    (8,) (scratch): 8 partial sums of every 8th element, then the rest in turn."""
    if n < 8:
        return _sequential(a, lo, n, r)
    for j in range(8):
        r[j] = a[lo + j]
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[lo + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@jit
def _pairwise(a: np.ndarray, lo: int, n: int, r: np.ndarray, sums: np.ndarray) -> float:
    """numpy's pairwise sum of ``a[lo:lo + n]`` (1-D): blocks of :data:`BLOCK`, a longer run split
    in halves (the first a multiple of 8) whose sums are added. Without recursion (numba's cache
    does not keep recursive functions): a stack of runs to sum or to add up, and ``sums`` (64,)
    of the dtype of ``r`` (8,) holds the sums not yet added."""
    runs = np.empty((128, 3), dtype=np.int64)  # (start, length, 1: add the last two sums); 2 a halving
    runs[0, 0], runs[0, 1], runs[0, 2] = lo, n, 0
    k, m = 1, 0
    while k:
        k -= 1
        start, length, add = runs[k, 0], runs[k, 1], runs[k, 2]
        if add:
            m -= 1
            sums[m - 1] = sums[m - 1] + sums[m]
        elif length <= BLOCK:
            sums[m] = _block(a, start, length, r)
            m += 1
        else:
            half = length // 2
            half -= half % 8
            runs[k, 0], runs[k, 1], runs[k, 2] = start, length, 1
            runs[k + 1, 0], runs[k + 1, 1], runs[k + 1, 2] = start + half, length - half, 0
            runs[k + 2, 0], runs[k + 2, 1], runs[k + 2, 2] = start, half, 0
            k += 3
    return sums[0]  # type: ignore[no-any-return]


@jit
def means32(x: np.ndarray) -> np.ndarray:
    """(k,) float32 ``x.mean(axis=1)`` of ``x`` (k, n) float32 (any strides), n >= 1."""
    r, sums = np.empty(8, dtype=np.float32), np.empty(64, dtype=np.float32)
    n, interleaved = x.shape[1], _interleaved(x)
    out = np.empty(x.shape[0], dtype=np.float32)
    for row in range(x.shape[0]):
        total = _sequential(x[row], 0, n, r) if interleaved else _pairwise(x[row], 0, n, r, sums)
        out[row] = total / np.float32(n)
    return out


@jit
def means64(x: np.ndarray, buffer: int) -> np.ndarray:
    """(k,) float64 ``x.mean(axis=1, dtype=np.float64)`` of ``x`` (k, n) float32 (any strides),
    n >= 1: rows summed pairwise in chunks of ``buffer`` elements (:func:`numpy.getbufsize`), or
    interleaved rows element after element."""
    r, sums = np.empty(8), np.empty(64)
    n, interleaved = x.shape[1], _interleaved(x)
    out = np.empty(x.shape[0])
    for row in range(x.shape[0]):
        if interleaved:  # one pass, whatever the buffer
            total = _sequential(x[row], 0, n, r)
        else:
            total, lo = 0.0, 0
            while lo < n:
                m = min(buffer, n - lo)
                total += _pairwise(x[row], lo, m, r, sums)
                lo += m
        out[row] = total / n
    return out
