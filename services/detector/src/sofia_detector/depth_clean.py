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

EIGHT = np.ones((3, 3), dtype=bool)
SHIFTS = ((0, 1), (1, 0), (1, 1), (1, -1))


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


def consistent_at(c: np.ndarray, mask: np.ndarray, delta: float, min_neighbours: int = 2) -> np.ndarray:
    """``mask`` (h, w) bool keeping only its pixels that pass :func:`consistent` (computed at those
    pixels only: cheap for sparse masks)."""
    r, q = np.nonzero(mask)
    if r.size == 0:
        return mask
    _, h, w = c.shape
    count = np.zeros(r.size, dtype=np.int8)
    p = c[:, r, q]
    d2 = np.float32(delta * delta)
    for dr, dq in ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)):
        rr, qq = r + dr, q + dq
        inside = (rr >= 0) & (rr < h) & (qq >= 0) & (qq < w)
        diff = c[:, np.clip(rr, 0, h - 1), np.clip(qq, 0, w - 1)] - p
        with np.errstate(invalid="ignore"):
            close = np.einsum("kn,kn->n", diff, diff) < d2
        count += close & inside
    out = np.zeros_like(mask)
    keep = count >= min_neighbours
    out[r[keep], q[keep]] = True
    return out


def pixel_spacing(m: np.ndarray, stride: int) -> float:
    """Median distance between horizontally adjacent pixels of the full-resolution image, metres.

    m: (3, h, w) float32 coordinates of the coarse grid (every ``stride``-th pixel), metres.
    """
    step = m[:, ::8, 1:] - m[:, ::8, :-1]
    d = np.sqrt(np.einsum("kij,kij->ij", step, step)).ravel()
    d = d[np.isfinite(d)]
    return float(np.median(d)) / stride if d.size else 0.0012


def chroma(rgb: np.ndarray) -> np.ndarray:
    """(..., 4) float32 shading-invariant colour: chromaticity (r, g, b) / sum and log brightness."""
    x = rgb.astype(np.float32) + 8.0
    s = x.sum(axis=-1, keepdims=True)
    return np.concatenate([3.0 * x / s, 0.5 * np.log(s)], axis=-1)


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
    r, c = np.nonzero(labels)
    lab = labels[r, c]
    feat = chroma(rgb[r, c])
    counts = np.bincount(lab, minlength=n + 1).astype(np.float32)
    sums = np.stack([np.bincount(lab, weights=feat[:, k], minlength=n + 1) for k in range(4)], axis=1)
    mean = sums / np.maximum(counts, 1)[:, None]
    grown = labels.copy()
    for _ in range(steps):
        dil = ndimage.maximum_filter(grown, size=3)
        cand = invalid & (grown == 0) & (dil > 0)
        if not cand.any():
            break
        r, c = np.nonzero(cand)
        ok = colour_distance(chroma(rgb[r, c]), mean[dil[r, c]]) < tol
        grown[r[ok], c[ok]] = dil[r[ok], c[ok]]
    return ndimage.label(grown > 0, structure=EIGHT)
