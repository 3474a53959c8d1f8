"""Connected components, the square maximum filter and hole filling of pixel grids, compiled (numba).

The detector labels a dozen small grids per cloud (the coarse seeds, each object's window, its top,
the board's outline). ``scipy.ndimage.label``, ``maximum_filter`` and ``binary_fill_holes`` cost
20-150 us per call on them, most of it setting up; these give the same arrays in a few
microseconds: labels numbered 1..n in the order in which a row-major scan first meets each
component, as SciPy numbers them.
"""

from __future__ import annotations

import numpy as np

from .kernels import jit


@jit
def _root(parent: np.ndarray, i: int) -> int:
    """The root of provisional label ``i`` (path halving)."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@jit
def _union(parent: np.ndarray, i: int, j: int) -> int:
    """Join the trees of provisional labels ``i`` and ``j`` under the older root; returns it."""
    i, j = _root(parent, i), _root(parent, j)
    if i < j:
        parent[j] = i
        return i
    parent[i] = j
    return j


@jit
def label8_jit(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """:func:`label8` of a C-contiguous bool mask, callable from compiled code."""
    h, w = mask.shape
    out = np.zeros((h, w), dtype=np.int32)
    parent = np.zeros(h * w // 2 + w + 2, dtype=np.int32)  # new labels: at most ceil(h/2) ceil(w/2)
    n = 0
    for r in range(h):
        for c in range(w):
            if not mask[r, c]:
                continue
            # the neighbours already scanned: a b c above, d left. b touches all of a, c and d
            up = r > 0
            b = out[r - 1, c] if up else 0
            if b:
                out[r, c] = b
                continue
            a = out[r - 1, c - 1] if up and c > 0 else 0
            cc = out[r - 1, c + 1] if up and c < w - 1 else 0
            d = out[r, c - 1] if c > 0 else 0
            if cc:
                left = a if a else d  # a and d touch each other
                out[r, c] = _union(parent, cc, left) if left else cc
            elif a:
                out[r, c] = a
            elif d:
                out[r, c] = d
            else:
                n += 1
                parent[n] = n
                out[r, c] = n
    final = np.zeros(n + 1, dtype=np.int32)
    m = 0
    for r in range(h):
        for c in range(w):
            if out[r, c] > 0:
                k = _root(parent, out[r, c])
                if final[k] == 0:
                    m += 1
                    final[k] = m
                out[r, c] = final[k]
    return out, m


def label8(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """(labels (h, w) int32, n): the 8-connected components of ``mask`` (h, w) bool, numbered
    1..n as ``scipy.ndimage.label(mask, structure=np.ones((3, 3)))`` numbers them; 0 off the mask."""
    return label8_jit(np.ascontiguousarray(mask, dtype=np.bool_))  # type: ignore[no-any-return]


@jit
def label_boxes(labels: np.ndarray, n: int) -> np.ndarray:
    """(n, 4) int64 bounding box ``(row start, row stop, col start, col stop)`` (stops exclusive) of
    each label 1..n of ``labels`` (h, w) int, as ``scipy.ndimage.find_objects`` slices them; a label
    without pixels gets (0, 0, 0, 0)."""
    h, w = labels.shape
    boxes = np.zeros((n, 4), dtype=np.int64)
    boxes[:, 0], boxes[:, 2] = h, w
    for r in range(h):
        for c in range(w):
            k = labels[r, c] - 1
            if k >= 0:
                boxes[k, 0], boxes[k, 1] = min(boxes[k, 0], r), max(boxes[k, 1], r + 1)
                boxes[k, 2], boxes[k, 3] = min(boxes[k, 2], c), max(boxes[k, 3], c + 1)
    for k in range(n):
        if boxes[k, 1] == 0:
            boxes[k] = 0
    return boxes


@jit
def label_sizes(labels: np.ndarray, n: int) -> np.ndarray:
    """(n + 1,) int64 pixel count of each label 0..n of ``labels`` (h, w) int, as
    ``np.bincount(labels.ravel(), minlength=n + 1)`` counts them (0: the pixels off every label)."""
    sizes = np.zeros(n + 1, dtype=np.int64)
    for r in range(labels.shape[0]):
        for c in range(labels.shape[1]):
            sizes[labels[r, c]] += 1
    return sizes


@jit
def largest_label(labels: np.ndarray, n: int) -> tuple[int, int]:
    """(label, pixel count) of the largest of the labels 1..n of ``labels`` (h, w) int, the first
    of equal ones in scan order (as ``np.argmax`` of the sizes picks it); (-1, 0), a label no
    pixel has, when n is 0."""
    if n == 0:
        return -1, 0
    sizes = label_sizes(labels, n)
    keep = 1
    for k in range(2, n + 1):
        if sizes[k] > sizes[keep]:
            keep = k
    return keep, sizes[keep]


@jit
def max_filter_jit(a: np.ndarray, k: int) -> np.ndarray:
    """:func:`max_filter` of a C-contiguous int32 array over a (2 k + 1) square, callable from
    compiled code."""
    h, w = a.shape
    out = np.zeros_like(a)
    for r in range(h):  # each non-zero pixel raises the square around it
        for c in range(w):
            v = a[r, c]
            if v == 0:
                continue
            for rr in range(max(r - k, 0), min(r + k + 1, h)):
                for cc in range(max(c - k, 0), min(c + k + 1, w)):
                    if out[rr, cc] < v:
                        out[rr, cc] = v
    return out


def max_filter(a: np.ndarray, size: int) -> np.ndarray:
    """(h, w) the largest value of ``a`` (h, w) int32 >= 0 within a ``size`` x ``size`` square (odd)
    around each pixel, as ``scipy.ndimage.maximum_filter(a, size=size)`` (whose ``reflect`` border
    repeats values already in the square). Its cost grows with the non-zero pixels: for labels."""
    return max_filter_jit(np.ascontiguousarray(a, dtype=np.int32), size // 2)  # type: ignore[no-any-return]


@jit
def fill_holes_jit(mask: np.ndarray) -> np.ndarray:
    """:func:`fill_holes` of a C-contiguous bool mask, callable from compiled code."""
    h, w = mask.shape
    outside = np.zeros((h, w), dtype=np.bool_)
    stack = np.empty(h * w, dtype=np.int64)
    n = 0
    for r in range(h):  # the background on the image border
        for c in range(w):
            if (r == 0 or r == h - 1 or c == 0 or c == w - 1) and not mask[r, c]:
                outside[r, c] = True
                stack[n] = r * w + c
                n += 1
    while n > 0:  # and all background 4-connected to it
        n -= 1
        r, c = divmod(stack[n], w)
        for rr, cc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= rr < h and 0 <= cc < w and not mask[rr, cc] and not outside[rr, cc]:
                outside[rr, cc] = True
                stack[n] = rr * w + cc
                n += 1
    return ~outside


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """(h, w) bool ``mask`` (h, w) with its holes filled: the background not 4-connected to the
    image border, as ``scipy.ndimage.binary_fill_holes(mask)``."""
    return fill_holes_jit(np.ascontiguousarray(mask, dtype=np.bool_))  # type: ignore[no-any-return]
