"""The per-object steps give what their plain numpy forms give, on random windows and on arrays
laid out as a received cloud's (read-only, strided, colours in reverse order); the circle and cap
fits recover the shapes their points were drawn from."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from sofia_detector.geometry.grid import grow
from sofia_detector.geometry.points import change_frame, coords, points_in_frame
from sofia_detector.objects import colour, rim
from sofia_detector.objects.caps import fit_top
from sofia_detector.objects.rim import fit_circle
from sofia_schemas import Board


def _windows(seed: int, n: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(mask (h, w) bool, heights (h, w) float32 with NaN holes, colours (h, w, 3) uint8 as a
    received cloud gives them: a read-only view of bytes, in reverse channel order)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        h, w = int(rng.integers(6, 50)), int(rng.integers(6, 50))
        mask = ndimage.binary_dilation(rng.random((h, w)) > 0.97, iterations=int(rng.integers(1, 5)))
        z = np.where(mask, 0.03, 0.0) + rng.normal(0.0, 0.004, (h, w))
        z[rng.random((h, w)) < rng.uniform(0.0, 0.4)] = np.nan
        z[:, : int(rng.integers(0, 8))] = np.nan  # an invalid band
        palette = np.array([[30, 60, 200], [200, 30, 30], [230, 230, 230]], dtype=np.uint8)
        bgr0 = np.zeros((h, w, 4), dtype=np.uint8)
        bgr0[..., :3] = palette[rng.integers(0, 3, (h, w))][..., ::-1]
        rgb = np.frombuffer(bgr0.tobytes(), dtype=np.uint8).reshape(h, w, 4)[..., 2::-1]
        out.append((mask, z.astype(np.float32), rgb))
    return out


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_points_in_frame_is_change_frame_of_the_copied_points(dtype: type) -> None:
    rng = np.random.default_rng(4)
    T = np.eye(4)
    T[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    T[:3, 3] = (0.5, -0.2, 0.1)
    xyzw = rng.normal(0.0, 0.5, (24, 32, 4)).astype(dtype)
    xyzw[rng.random((24, 32)) < 0.2, :3] = np.nan
    received = np.frombuffer(xyzw.tobytes(), dtype=dtype).reshape(24, 32, 4)[..., :3]  # read-only, strided
    for p in (received, received[::4, ::4], np.array(received), received.reshape(-1, 3)[::3]):
        assert np.allclose(
            points_in_frame(p, T), change_frame(coords(p), T), rtol=0, atol=1e-6, equal_nan=True
        )


def _old_rim_pixels(grid: np.ndarray, h: np.ndarray, below: float) -> tuple[np.ndarray, np.ndarray]:
    padded = np.full((h.shape[0] + 2, h.shape[1] + 2), np.nan, dtype=np.float32)
    padded[1:-1, 1:-1] = h
    with np.errstate(invalid="ignore"):
        low = padded < below
    low[1:-1, 1:-1] |= grid
    ok = grid & grow(~grid, 3)
    for dr in range(3):
        for dc in range(3):
            ok &= low[dr : dr + grid.shape[0], dc : dc + grid.shape[1]]
    return np.nonzero(ok)  # type: ignore[return-value]


def test_rim_pixels_are_the_numpy_forms() -> None:
    for mask, z, _ in _windows(5, 150):
        got = rim._rim_pixels(mask, z, np.float32(0.02))
        want = _old_rim_pixels(mask, z, 0.02)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


def test_board_white_is_the_numpy_form() -> None:
    board = Board.default()
    rng = np.random.default_rng(8)
    centres = board.field_centers_board()
    allowed = np.array([[board.is_allowed(i, j) for j in range(board.cols)] for i in range(board.rows)])
    for _ in range(20):
        T = np.eye(4)
        yaw = rng.uniform(-0.1, 0.1)
        T[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
        T[:2, 3] = rng.normal(0.0, 0.01, 2)
        xy = rng.uniform(-0.3, 0.3, (2, 40, 50))
        m = np.concatenate([xy, rng.normal(0.0, 0.003, (1, 40, 50))]).astype(np.float32)
        m[:, rng.random((40, 50)) < 0.1] = np.nan
        rgb = rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)
        with np.errstate(invalid="ignore"):
            r, c = np.nonzero(np.abs(m[2, ::3, ::3]) < 0.004)
        r, c = 3 * r, 3 * c
        p = (T[:2, :2] @ m[:2, r, c]).T + T[:2, 3]
        rc = board.field_of_board_xy(p)
        i, j = np.clip(rc[:, 0], 0, None), np.clip(rc[:, 1], 0, None)
        middle = np.all(np.abs(p - centres[i, j]) < 0.3 * np.array(board.field_size), axis=1)
        white = (rc[:, 0] >= 0) & middle & ~allowed[i, j]
        want = (
            np.median(rgb[r[white], c[white]], axis=0)
            if np.count_nonzero(white) >= colour.MIN_WHITE_PIXELS
            else None
        )
        got = colour.board_white(m, rgb, T, board, 0.004)
        assert (got is None and want is None) or np.allclose(got, want)


def test_circle_and_cap_fits_recover_the_shapes_they_were_drawn_from() -> None:
    rng = np.random.default_rng(9)
    for _ in range(50):
        t = rng.uniform(0.0, rng.uniform(1.0, 2 * np.pi), 40)
        xy = np.stack([0.1 + 0.03 * np.cos(t), -0.2 + 0.03 * np.sin(t)], axis=1) + rng.normal(
            0, 1e-5, (40, 2)
        )
        centre, radius, rms = fit_circle(xy)
        np.testing.assert_allclose(centre, (0.1, -0.2), atol=2e-4)
        assert radius == pytest.approx(0.03, abs=2e-4) and rms < 3e-5
        x, y = rng.normal(0.0, 0.02, (2, 200))
        h = (0.05 + 0.1 * x - 0.2 * y - 8.0 * (x * x + y * y) + rng.normal(0, 1e-5, 200)).astype(np.float32)
        fit = fit_top(x, y, h)
        assert fit is not None
        np.testing.assert_allclose(fit[0], (0.05, 0.1, -0.2, -8.0), rtol=1e-3, atol=1e-4)
        assert 0 < fit[1] < 0.01  # the standard error of d: tiny against |d| = 8
    assert fit_circle(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))[1] == np.inf  # collinear
    assert fit_top(*np.zeros((3, 10))) is None  # all at one point: singular
