"""Object colours by name: the median over the upper faces, white-balanced on the board's white
fields, named after the nearest palette colour in chromaticity and log brightness; divided by the
diffuse light a tilted face gets (:func:`lit_share`) when the name could be a shaded brighter one.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from sofia_schemas import Board

from ..depth.clean import chroma, colour_distance
from ..geometry.samples import median
from ..params import DEFAULT_PALETTE

WHITE_REFERENCE = (235.0, 235.0, 230.0)  # sRGB of the board's white fields in the palette's light
MIN_WHITE_PIXELS = 20
SAME_HUE = 0.1  # chromaticity distance of palette colours that differ by brightness alone
WHITE_STEP = 3  # board_white samples every third row and column of the coarse grid
NORMAL_STEP = 2  # pixels between the points whose differences give a face's normal


def board_white(
    m_plane: np.ndarray, rgb_coarse: np.ndarray, T_board_plane: np.ndarray, board: Board, band: float
) -> np.ndarray | None:
    """(3,) median colour of the board's white fields, or None: pixels of m_plane (3, h, w)
    float32 (plane frame, metres) and rgb_coarse (h, w, 3) uint8 on every third row and column,
    within ``band`` of the plane and in the middle 60 % of a white field."""
    white_at = _white_fields(board)
    A = T_board_plane[:2, [0, 1, 3]]
    m, rgb = m_plane[:, ::WHITE_STEP, ::WHITE_STEP], rgb_coarse[::WHITE_STEP, ::WHITE_STEP]
    with np.errstate(invalid="ignore"):
        keep = np.abs(m[2]) < band
        at = []
        for k in (0, 1):  # field index and place within it along the board's x, then y
            u = (A[k, 0] * m[0] + A[k, 1] * m[1] + A[k, 2]) / board.field_size[k] + white_at.shape[k] / 2 - 1
            i = np.floor(u)
            keep &= np.abs(u - i - 0.5) < 0.3  # the middle 60 % of the field
            at.append(np.fmin(np.fmax(i, -1), white_at.shape[k] - 2).astype(np.intp) + 1)  # NaN: -1
    keep &= white_at[at[0], at[1]]
    white = rgb[keep]
    if white.shape[0] < MIN_WHITE_PIXELS:
        return None
    return median(white)  # type: ignore[no-any-return]


@lru_cache(maxsize=16)
def _white_fields(board: Board) -> np.ndarray:
    """(rows + 2, cols + 2) bool: the board's white fields, with a border of False around them."""
    white = np.zeros((board.rows + 2, board.cols + 2), dtype=bool)
    white[1:-1, 1:-1] = [[not board.is_allowed(i, j) for j in range(board.cols)] for i in range(board.rows)]
    return white


def lit_share(window: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(n,) light ``(1 + |n_z|) / 2`` the faces at pixels (rows, cols) (n,) of window (3, h, w)
    float32 (board frame, metres) get relative to the board; NaN where no normal is measured. The
    normal: the cross product of the differences of the neighbours :data:`NORMAL_STEP` pixels
    away; none where a difference's two halves disagree (a depth step)."""
    _, h, w = window.shape
    k = NORMAL_STEP
    if h <= 2 * k or w <= 2 * k:
        return np.full(rows.size, np.nan)
    at = np.clip(rows, k, h - 1 - k) * w + np.clip(cols, k, w - 1 - k)
    p = window.reshape(3, -1)[:, at[None, :] + np.array([[0], [k], [-k], [k * w], [-k * w]])]  # (3, 5, n)
    fwd, back = p[:, 1::2] - p[:, :1], p[:, :1] - p[:, 2::2]  # (3, 2, n) along the columns and the rows
    f2, b2 = np.einsum("kan,kan->an", fwd, fwd), np.einsum("kan,kan->an", back, back)
    d = fwd - back
    with np.errstate(invalid="ignore"):
        ok = np.all(np.einsum("kan,kan->an", d, d) < 0.25 * np.maximum(f2, b2), axis=0)
    diff = fwd + back  # (3, 2, n): the differences along the columns and the rows
    normal = np.cross(diff[:, 0], diff[:, 1], axis=0)  # (3, n)
    norm = np.linalg.norm(normal, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        lit = (1.0 + np.abs(normal[2]) / norm) / 2.0
    return np.where(ok & (norm > 0), lit, np.nan)


@lru_cache(maxsize=16)
def _palette_chroma(palette: tuple[tuple[str, tuple[int, int, int]], ...]) -> np.ndarray:
    """(k, 4) chroma of the k colours of ``palette``."""
    return chroma(np.array([p for _, p in palette], dtype=np.float64))


@lru_cache(maxsize=16)
def shaded_like_another(name: str, palette: tuple[tuple[str, tuple[int, int, int]], ...]) -> bool:
    """Whether ``name`` could be a shaded brighter colour of ``palette`` of its chromaticity."""
    feats = _palette_chroma(palette)
    mine = feats[[n for n, _ in palette].index(name)]
    return any(f[3] > mine[3] and float(colour_distance(f[:3], mine[:3])) < SAME_HUE for f in feats)


def name_colour(
    rgb: np.ndarray,
    white: np.ndarray | None,
    palette: tuple[tuple[str, tuple[int, int, int]], ...] = DEFAULT_PALETTE,
) -> tuple[str, tuple[int, int, int]]:
    """(name, white-balanced sRGB) of an observed colour rgb (3,) 0-255; white: (3,) the board's
    observed white, or None (no balance)."""
    balanced = np.asarray(rgb, dtype=np.float64)
    if white is not None:
        balanced = balanced * np.asarray(WHITE_REFERENCE) / np.maximum(white, 1.0)
    balanced = np.clip(balanced, 0.0, 255.0)
    d = colour_distance(chroma(balanced)[None, :], _palette_chroma(palette))
    name = palette[int(np.argmin(d))][0]
    r, g, b = (int(v) for v in np.round(balanced))
    return name, (r, g, b)
