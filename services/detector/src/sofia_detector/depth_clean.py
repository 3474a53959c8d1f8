"""Real depth on the organized grid: flying pixels, depth noise, holes bridged by colour.

A stereo camera mixes foreground and background where a matching window straddles a depth edge:
those flying pixels float between the two surfaces, each at its own depth. A point on a real
surface has neighbours on the same surface within a few pixel spacings in 3D; a flying pixel
seldom has two. Dark surfaces return no depth at all in blobs; their colour is still seen, so
missing pixels of an object's colour join its pieces.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .pixels import grow, median, where

EIGHT = np.ones((3, 3), dtype=bool)
SHIFTS = ((0, 1), (1, 0), (1, 1), (1, -1))
NEIGHBOURS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
STEPS = np.array(NEIGHBOURS, dtype=np.intp)  # (8, 2) row and column steps to the neighbours


def consistent(c: np.ndarray, delta: float, min_neighbours: int = 2) -> np.ndarray:
    """(h, w) bool: pixels with at least ``min_neighbours`` of their 8 neighbours within ``delta``.

    c: (3, h, w) float32 coordinates of an organized cloud (any frame), metres, NaN allowed.
    delta: 3D distance, metres. NaN pixels are never consistent.
    """
    _, h, w = c.shape
    count = np.zeros((h, w), dtype=np.int8)
    d2 = np.float32(delta * delta)
    for dr, dc in SHIFTS:
        ca, cb = (
            (slice(0, w - 1), slice(1, w))
            if dc == 1
            else (slice(1, w), slice(0, w - 1))
            if dc == -1
            else (slice(0, w), slice(0, w))
        )
        ra, rb = slice(0, h - dr), slice(dr, h)
        diff = c[:, ra, ca] - c[:, rb, cb]
        with np.errstate(invalid="ignore"):
            close = np.einsum("kij,kij->ij", diff, diff) < d2
        count[ra, ca] += close
        count[rb, cb] += close
    return count >= min_neighbours


def _padded(a: np.ndarray, fill: float | int) -> np.ndarray:
    """``a`` (..., h, w) with a one-pixel frame of ``fill`` around its last two axes, flattened
    over them: (..., (h + 2) * (w + 2))."""
    *lead, h, w = a.shape
    out = np.full((*lead, h + 2, w + 2), fill, dtype=a.dtype)
    out[..., 1:-1, 1:-1] = a
    return out.reshape(*lead, -1)


def _neighbours(r: np.ndarray, q: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices into a :func:`_padded` image (unpadded width ``w``) of the pixels (r, q) (n,):
    (n,) the pixels themselves and (8, n) their 8 neighbours."""
    here = (r + 1) * (w + 2) + (q + 1)
    offsets = np.array([dr * (w + 2) + dq for dr, dq in NEIGHBOURS], dtype=np.intp)
    return here, here[None, :] + offsets[:, None]


def consistent_at(c: np.ndarray, mask: np.ndarray, delta: float, min_neighbours: int = 2) -> np.ndarray:
    """``mask`` (h, w) bool keeping only its pixels that pass :func:`consistent` (computed at those
    pixels only: cheap for sparse masks)."""
    r, q = where(mask)
    if r.size == 0:
        return mask
    h, w = mask.shape
    rr, qq = r + STEPS[:, :1], q + STEPS[:, 1:]  # (8, n) the neighbours
    inside = (rr >= 0) & (rr < h) & (qq >= 0) & (qq < w)
    around = np.minimum(np.maximum(rr, 0), h - 1) * w + np.minimum(np.maximum(qq, 0), w - 1)
    flat = c.reshape(3, -1)
    diff = flat[:, around] - flat[:, None, r * w + q]  # (3, 8, n)
    with np.errstate(invalid="ignore"):
        close = np.einsum("kmn,kmn->mn", diff, diff) < np.float32(delta * delta)
    close &= inside
    out = np.zeros_like(mask)
    keep = np.count_nonzero(close, axis=0) >= min_neighbours
    out[r[keep], q[keep]] = True
    return out


def pixel_spacing(m: np.ndarray, stride: int) -> float:
    """Median distance between horizontally adjacent pixels of the full-resolution image, metres.

    m: (3, h, w) float32 coordinates of the coarse grid (every ``stride``-th pixel), metres.
    """
    step = m[:, ::8, 1:] - m[:, ::8, :-1]
    d = np.sqrt(np.einsum("kij,kij->ij", step, step)).ravel()
    d = d[np.isfinite(d)]
    return float(median(d)) / stride if d.size else 0.0012


def chroma(rgb: np.ndarray) -> np.ndarray:
    """(..., 4) float32 shading-invariant colour: chromaticity (r, g, b) / sum and log brightness."""
    x = rgb.astype(np.float32) + 8.0
    s = x.sum(axis=-1, keepdims=True)
    return np.concatenate([3.0 * x / s, 0.5 * np.log(s)], axis=-1)


def median_chroma(rgb: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(4,) :func:`chroma` of the median colour of the pixels (rows, cols) (n,) of ``rgb`` (h, w, 3)
    uint8: an object's own colour."""
    return chroma(median(rgb[rows, cols].astype(np.float64)))


def label_means(labels: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """(n + 1, k) float64 mean of ``values`` (m, k) per label of ``labels`` (m,) int in 0..n (0 for
    a label without values)."""
    counts = np.bincount(labels, minlength=n + 1).astype(np.float64)
    sums = np.stack(
        [np.bincount(labels, weights=values[:, c], minlength=n + 1) for c in range(values.shape[1])], axis=1
    )
    return sums / np.maximum(counts, 1.0)[:, None]  # type: ignore[no-any-return]


def colour_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of :func:`chroma` features a (..., 4) and b (..., 4)."""
    d = a - b
    return np.sqrt(np.einsum("...k,...k->...", d, d))


def bridge(
    seeds: np.ndarray, invalid: np.ndarray, rgb: np.ndarray | None, tol: float, steps: int = 3
) -> tuple[np.ndarray, int]:
    """Components of ``seeds`` (h, w) bool joined across ``invalid`` (h, w) pixels of their colour.

    rgb: (h, w, 3) uint8 colours aligned with the grid, or None (no bridging). Each seed
    component grows up to ``steps`` pixels into invalid pixels within ``tol`` of its mean
    :func:`chroma`. Returns (labels (h, w) int, n) of the joined components (grown pixels
    included).
    """
    labels, n = ndimage.label(seeds, structure=EIGHT)
    if rgb is None or n < 2 or not invalid.any():
        return labels, n
    r, c = where(labels)
    lab = labels[r, c]
    mean = label_means(lab, chroma(rgb[r, c]), n)
    r, c = where(invalid & grow(seeds, 2 * steps + 1))  # the missing pixels growth can reach
    if r.size == 0:
        return labels, n
    colour = chroma(rgb[r, c])
    grown = _padded(labels, 0)  # flat, grown in place
    here, around = _neighbours(r, c, labels.shape[1])
    todo = np.ones(r.size, dtype=bool)
    for _ in range(steps):
        lab = grown[around].max(axis=0)  # the largest label around each pixel
        ok = todo & (lab > 0)
        if not ok.any():
            break
        ok[ok] = colour_distance(colour[ok], mean[lab[ok]]) < tol
        grown[here[ok]] = lab[ok]
        todo &= ~ok
    if todo.all():  # nothing joined
        return labels, n
    inner = grown.reshape(labels.shape[0] + 2, -1)[1:-1, 1:-1]
    return ndimage.label(inner > 0, structure=EIGHT)
