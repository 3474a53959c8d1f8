"""Real depth on the organized grid. A flying pixel (stereo matching across a depth edge) seldom
has two neighbours within a few pixel spacings in 3D, a point on a real surface has; dark surfaces
lose depth in blobs but keep their colour, so missing pixels of an object's colour join its pieces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.compiled import jit
from ..geometry.grid import grow, label8, max_filter, where
from ..geometry.samples import median

EIGHT = np.ones((3, 3), dtype=bool)


@jit
def _consistent_at(c: np.ndarray, mask: np.ndarray, d2: np.float32, min_neighbours: int) -> np.ndarray:
    """:func:`consistent_at` in one pass. Kept: 38 us against 284 us per call for its numpy form
    (0.12 against 0.85 ms per cloud) on 28 realistic scenes."""
    _, h, w = c.shape
    out = np.zeros((h, w), dtype=np.bool_)
    for r in range(h):
        for q in range(w):
            if not mask[r, q]:
                continue
            x, y, z = c[0, r, q], c[1, r, q], c[2, r, q]
            k = 0
            for rr in range(max(r - 1, 0), min(r + 2, h)):
                for qq in range(max(q - 1, 0), min(q + 2, w)):
                    if rr != r or qq != q:
                        dx, dy, dz = c[0, rr, qq] - x, c[1, rr, qq] - y, c[2, rr, qq] - z
                        k += dx * dx + dy * dy + dz * dz < d2  # False for NaN
            out[r, q] = k >= min_neighbours
    return out


def consistent_at(c: np.ndarray, mask: np.ndarray, delta: float, min_neighbours: int = 2) -> np.ndarray:
    """``mask`` (h, w) bool without flying pixels: only pixels with ``min_neighbours`` of their 8
    neighbours within ``delta`` metres in 3D. c: (3, h, w) float32, any frame, metres, NaN allowed."""
    c = np.ascontiguousarray(c, dtype=np.float32)
    return _consistent_at(c, np.ascontiguousarray(mask), np.float32(delta * delta), min_neighbours)  # type: ignore[no-any-return]


def pixel_spacing(m: np.ndarray, stride: int) -> float:
    """Median distance (metres) of horizontally adjacent full-resolution pixels, from the coarse
    grid m (3, h, w) float32 of every ``stride``-th pixel."""
    with np.errstate(invalid="ignore", over="ignore"):
        d = np.linalg.norm(np.diff(m[:, ::8], axis=2), axis=0)
    d = d[np.isfinite(d)]
    return float(median(d)) / stride if d.size else 0.0012


def chroma(rgb: np.ndarray, dtype: type = np.float32) -> np.ndarray:
    """(..., 4) shading-invariant colour of ``dtype``: chromaticity (r, g, b) / sum and log brightness."""
    x = rgb.astype(dtype) + 8.0
    s = x.sum(axis=-1, keepdims=True)
    return np.concatenate([3.0 * x / s, 0.5 * np.log(s)], axis=-1)


def median_chroma(rgb: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(4,) :func:`chroma` of the median colour of pixels (rows, cols) (n,) of rgb (h, w, 3) uint8."""
    return chroma(median(rgb[rows, cols]))


def of_colour(px: np.ndarray, own: np.ndarray, tol: float) -> np.ndarray:
    """(...) bool: the colours ``px`` (..., 3) uint8 within ``tol`` of ``own`` (4,), a :func:`chroma`."""
    return colour_distance(chroma(px), own) < tol  # type: ignore[no-any-return]


def label_means(labels: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """(n + 1, k) float64 mean of values (m, k) per label 0..n of labels (m,) int (0 when empty)."""
    counts = np.bincount(labels, minlength=n + 1).astype(np.float64)
    sums = np.stack(
        [np.bincount(labels, weights=values[:, c], minlength=n + 1) for c in range(values.shape[1])], axis=1
    )
    return sums / np.maximum(counts, 1.0)[:, None]  # type: ignore[no-any-return]


def colour_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of :func:`chroma` features a (..., 4) and b (..., 4)."""
    d = a - b
    return np.sqrt(np.einsum("...k,...k->...", d, d))


@dataclass(frozen=True)
class Raised:
    """Pixels above the board: mask (h, w) bool without flying pixels; labels (h, w) int32 1..n of
    their components (0 off them; bridged pixels included)."""

    mask: np.ndarray
    labels: np.ndarray
    n: int


def raised_pixels(
    c: np.ndarray, lo: float, hi: float, delta: float, rgb: np.ndarray | None = None, tol: float = 0.0
) -> Raised:
    """The depth stage: pixels of c (3, h, w) float32 (z the height above the board, metres, NaN
    where missing) between ``lo`` and ``hi``, without flying pixels (:func:`consistent_at`), in
    components joined across missing depth of their colour (:func:`bridge`; rgb (h, w, 3) uint8)."""
    with np.errstate(invalid="ignore"):
        mask = consistent_at(c, (c[2] > lo) & (c[2] < hi), delta)
    labels, n = label8(mask) if rgb is None else bridge(mask, ~np.isfinite(c[2]), rgb, tol)
    return Raised(mask, labels, n)


def bridge(
    seeds: np.ndarray, invalid: np.ndarray, rgb: np.ndarray | None, tol: float, steps: int = 3
) -> tuple[np.ndarray, int]:
    """(labels (h, w) int, n): components of ``seeds`` (h, w) bool, each grown up to ``steps``
    pixels into ``invalid`` (h, w) pixels within ``tol`` of its mean :func:`chroma` (rgb (h, w, 3)
    uint8; None: no bridging), joined where they meet."""
    labels, n = label8(seeds)
    if rgb is None or n < 2 or not invalid.any():
        return labels, n
    on = labels > 0
    mean = label_means(labels[on], chroma(rgb[on], np.float64), n)  # each component's mean chroma
    rs, cs = where(invalid & grow(on, 2 * steps + 1))  # the missing pixels growth can reach
    feats, waiting = chroma(rgb[rs, cs], np.float64), np.ones(rs.size, dtype=bool)
    grown, joined = labels.copy(), False
    for _ in range(steps):  # a waiting pixel joins the largest label among its 8 neighbours, if near
        lab = np.where(waiting, max_filter(grown, 3)[rs, cs], 0)
        if not (lab > 0).any():
            break
        ok = (lab > 0) & (colour_distance(feats, mean[lab]) < tol)
        grown[rs[ok], cs[ok]] = lab[ok]
        waiting &= ~ok
        joined |= bool(ok.any())
    return label8(grown > 0) if joined else (labels, n)
