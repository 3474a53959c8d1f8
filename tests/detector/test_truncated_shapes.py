"""Centres of objects part of whose top is not seen, and parts that a depth step cuts off an object.

Scenes are organized clouds seen straight from above (1.5 mm pixels) on the default board: a round
top with a blob of missing depth over a third of it (a dark patch, the second imager's invalid
band or the image border cut it the same way), a square top with the same blob, and a bottle
whose narrow neck stands on a wide body (with the ring of missing depth a stereo camera leaves
along the step).
"""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector import detect
from sofia_detector.objects.rim import fit_circle
from sofia_schemas import Board

BOARD = Board.default()
STEP = 0.0015


def _scene(height_of, hole: tuple[float, float, float] | None = None, unseen=None) -> np.ndarray:  # type: ignore[no-untyped-def]
    """(H, W, 3) float32 cloud, base frame: the board (z = 0 around ``BOARD.center``) with heights
    ``height_of(du, dv)`` (offsets from a field's centre, metres); ``hole`` (du, dv, r): a disc
    of missing depth; ``unseen(dv, h)``: (H, W) bool, more missing depth."""
    u, v = np.meshgrid(np.arange(-0.26, 0.26, STEP), np.arange(-0.34, 0.34, STEP), indexing="ij")
    cx, cy = FIELD
    du, dv = u - cx, v - cy
    h = height_of(du, dv)
    p = np.stack([u, v, h], axis=-1)
    p[(np.abs(u) > 0.245) | (np.abs(v) > 0.32)] = np.nan  # beyond the board
    if hole is not None:
        p[np.hypot(du - hole[0], dv - hole[1]) < hole[2]] = np.nan
    if unseen is not None:
        p[unseen(dv, h)] = np.nan
    p[..., 0] += BOARD.center[0]
    p[..., 1] += BOARD.center[1]
    return p.astype(np.float32)


FIELD = tuple(BOARD.field_centers_board()[(1, 0)])  # board frame = base frame offset by the centre
TRUE_XY = np.array(FIELD) + np.array(BOARD.center[:2])


def _one(points: np.ndarray):  # type: ignore[no-untyped-def]
    det = detect(points, BOARD)
    assert det.status == "ok" and len(det.objects) == 1, det
    return det.objects[0]


def test_circle_fit_recovers_an_arc() -> None:
    a = np.linspace(-1.2, 1.9, 60)  # 178 degrees of arc
    rng = np.random.default_rng(1)
    xy = np.c_[0.3 + 0.03 * np.cos(a), -0.1 + 0.03 * np.sin(a)] + rng.normal(0, 2e-4, (60, 2))
    c, r, rms = fit_circle(xy)
    assert np.allclose(c, (0.3, -0.1), atol=5e-4) and abs(r - 0.03) < 5e-4 and rms < 4e-4


def test_round_top_with_a_third_unseen_keeps_its_centre() -> None:
    r, h = 0.035, 0.04
    cloud = _scene(lambda du, dv: np.where(np.hypot(du, dv) <= r, h, 0.0), hole=(-0.045, 0.0, 0.033))
    o = _one(cloud)
    # the seen part alone (the top from -12 mm to +35 mm) is centred 11.5 mm off
    assert np.hypot(*(np.array(o.center[:2]) - TRUE_XY)) < 0.002
    assert abs(o.extents[0] - 2 * r) < 0.004 and abs(o.extents[2] - h) < 0.002


def test_round_top_two_thirds_unseen_keeps_its_centre() -> None:
    """A puck of which a strip 16 mm wide is seen (the rest in missing depth, as in the second
    imager's invalid band): its rim against the board spans about 100 degrees, enough for the
    circle."""
    r, h = 0.031, 0.03
    cloud = _scene(lambda du, dv: np.where(np.hypot(du, dv) <= r, h, 0.0), hole=(-0.049, 0.0, 0.064))
    o = _one(cloud)
    assert np.hypot(*(np.array(o.center[:2]) - TRUE_XY)) < 0.003
    assert abs(o.extents[0] - 2 * r) < 0.005


def test_round_top_in_full_view_keeps_its_rectangle_centre() -> None:
    cloud = _scene(lambda du, dv: np.where(np.hypot(du, dv) <= 0.03, 0.05, 0.0))
    assert np.hypot(*(np.array(_one(cloud).center[:2]) - TRUE_XY)) < 0.001


def test_square_top_with_a_hole_is_no_circle() -> None:
    a = 0.03  # half side
    cloud = _scene(
        lambda du, dv: np.where((np.abs(du) <= a) & (np.abs(dv) <= a), 0.04, 0.0), hole=(-0.04, 0.0, 0.03)
    )
    o = _one(cloud)
    assert o.extents[0] <= 2 * a + 0.003, "the seen rectangle, not a circle around it"


@pytest.mark.parametrize("neck_r", [0.008, 0.011])
def test_a_neck_above_a_depth_step_belongs_to_the_bottle(neck_r: float) -> None:
    body_r, body_h, top = 0.035, 0.10, 0.15

    def height(du: np.ndarray, dv: np.ndarray) -> np.ndarray:
        rho = np.hypot(du, dv)
        h = np.where(rho <= neck_r, top, np.where(rho <= body_r, body_h, 0.0))
        return np.where((rho > neck_r) & (rho < neck_r + 0.003), np.nan, h)  # no depth at the step

    o = _one(_scene(height))
    assert abs(o.extents[2] - top) < 0.003, "the height is the neck's cap"
    assert abs(o.center[2] - top / 2) < 0.002 and np.hypot(*(np.array(o.center[:2]) - TRUE_XY)) < 0.002


def test_a_top_in_the_wider_invalid_band_of_near_surfaces_is_cut_by_the_image_edge() -> None:
    """The band on the left without depth is as wide as the disparity: wider for the object's top
    than for the board. The top's seen part starts right of the board's band edge, with nothing
    seen to its left: its centre is not trusted."""
    a = 0.03

    def unseen(dv: np.ndarray, h: np.ndarray) -> np.ndarray:
        return (dv < -a + 0.005) | ((h > 0) & (dv < -a + 0.02))

    cloud = _scene(lambda du, dv: np.where((np.abs(du) <= a) & (np.abs(dv) <= a), 0.05, 0.0), unseen=unseen)
    o = _one(cloud)
    assert "image_edge" in o.truncated and o.confidence < 0.5 and o.visibility < 0.95


def test_a_top_with_board_seen_on_its_left_is_not_cut() -> None:
    a = 0.03

    def unseen(dv: np.ndarray, h: np.ndarray) -> np.ndarray:
        return dv < -a - 0.02  # the band ends on the board, left of the object

    cloud = _scene(lambda du, dv: np.where((np.abs(du) <= a) & (np.abs(dv) <= a), 0.05, 0.0), unseen=unseen)
    o = _one(cloud)
    assert o.truncated == () and o.confidence > 0.9


def _black_box(du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    a = 0.03
    return np.where((np.abs(du) <= a) & (np.abs(dv) <= a), 0.04, 0.0)


def test_missing_depth_of_a_dark_tops_colour_is_the_top() -> None:
    """A black box whose top's left third returns no depth, nor does the board beside it (a shadow
    over both; the colour camera sees them) keeps its centre; the board (white) has another colour."""
    full = _scene(_black_box)
    rgb = np.where(full[..., 2:] > 0.02, np.array([25, 25, 28]), np.array([235, 235, 230])).astype(np.uint8)
    holed = _scene(_black_box, hole=(0.0, -0.07, 0.056))  # the top is seen from dv = -23 mm on
    before = detect(holed, BOARD).objects[0]  # without colours: the seen part
    assert np.hypot(*(np.array(before.center[:2]) - TRUE_XY)) > 0.003
    o = detect(holed, BOARD, rgb=rgb).objects[0]
    assert np.hypot(*(np.array(o.center[:2]) - TRUE_XY)) < 0.0015
    assert abs(o.extents[0] - 0.06) < 0.003 and abs(o.extents[1] - 0.06) < 0.003


def test_missing_depth_of_the_tops_colour_bordered_by_the_board_is_not_the_top() -> None:
    """The same box with a band of missing depth of its colour along one side and the board with
    depth right past it (a side face seen too obliquely, as flat-shaded renderings give): the band
    is not on the top's plane, so the footprint stays the top's."""
    a = 0.03
    full = _scene(_black_box)
    rgb = np.where(full[..., 2:] > 0.02, np.array([25, 25, 28]), np.array([235, 235, 230])).astype(np.uint8)
    du = np.arange(-0.26, 0.26, STEP)[:, None] - FIELD[0]
    dv = np.arange(-0.34, 0.34, STEP)[None, :] - FIELD[1]
    side = (np.abs(du) <= a) & (dv > -a - 0.012) & (dv < -a)  # 12 mm outside the top, board beyond
    rgb[side] = (25, 25, 28)
    cloud = _scene(_black_box, unseen=lambda dv_, h: side)
    o = detect(cloud, BOARD, rgb=rgb).objects[0]
    assert abs(o.extents[0] - 2 * a) < 0.003 and abs(o.extents[1] - 2 * a) < 0.003, o.extents
    assert np.hypot(*(np.array(o.center[:2]) - TRUE_XY)) < 0.0015


def _islands(n: int, height: float) -> tuple[np.ndarray, np.ndarray]:
    """The black box with missing depth over two fifths of its top and over the board beside it
    (the top is seen from dv = -4 mm on), except for ``n`` discs of 6 mm radius inside it at
    ``height``: (cloud, colours)."""
    full = _scene(_black_box)
    rgb = np.where(full[..., 2:] > 0.02, np.array([25, 25, 28]), np.array([235, 235, 230])).astype(np.uint8)
    holed = _scene(_black_box, hole=(0.0, -0.07, 0.07))
    du = np.arange(-0.26, 0.26, STEP)[:, None] - FIELD[0]
    dv = np.arange(-0.34, 0.34, STEP)[None, :] - FIELD[1]
    for k in range(n):
        island = np.hypot(du - (0.012 - 0.024 * k) * (n - 1), dv + 0.018) < 0.006
        holed[island] = full[island]
        holed[island, 2] = height
    return holed, rgb


@pytest.mark.parametrize("islands", [1, 2])
def test_pieces_of_a_dark_top_that_missing_depth_cuts_off_are_the_top(islands: int) -> None:
    """Islands of the top inside the missing patch (too small to count as part of its face) border
    it at the top's height: the patch is still the top, and the box keeps its centre."""
    holed, rgb = _islands(islands, 0.04)
    before = detect(holed, BOARD).objects[0]  # without colours: the seen part
    assert np.hypot(*(np.array(before.center[:2]) - TRUE_XY)) > 0.008
    o = detect(holed, BOARD, rgb=rgb).objects[0]
    assert np.hypot(*(np.array(o.center[:2]) - TRUE_XY)) < 0.0015, o.center
    assert abs(o.extents[0] - 0.06) < 0.003 and abs(o.extents[1] - 0.06) < 0.003, o.extents


def test_a_missing_patch_bordered_by_something_lower_than_the_top_is_not_the_top() -> None:
    """The same islands 20 mm below the top (a step, a side): the patch is not on the top's plane,
    so the footprint stays the seen part of the top."""
    holed, rgb = _islands(2, 0.02)
    o = detect(holed, BOARD, rgb=rgb).objects[0]
    assert o.extents[1] < 0.045, o.extents
