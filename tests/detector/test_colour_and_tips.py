"""Colours under shading, the height of a sparse tip, and objects seen only in specks.

Scenes are organized clouds seen straight from above (1.5 mm pixels) on the default board. The
colour images are shaded by a light from above with ambient light, ``0.3 + 0.7 cos(theta)`` of
the board's brightness for a face tilted by theta (another model than the detector's).
"""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector import detect
from sofia_detector.detect import DEFAULT_PARAMS
from sofia_detector.objects.colour import NORMAL_STEP, lit_share
from sofia_detector.objects.footprint import estimate_object
from sofia_detector.segment.points import ObjectPoints
from sofia_schemas import Board

BOARD = Board.default()
STEP = 0.0015
FIELD = tuple(BOARD.field_centers_board()[(1, 0)])
WHITE = np.array([235.0, 235.0, 230.0])


def _cone_scene(height: float, radius: float, paint: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) float32 cloud (base frame) of the board with a cone on field (1, 0), and its
    (H, W, 3) uint8 colours: the board white, the cone ``paint``, shaded by its flanks' tilt."""
    u, v = np.meshgrid(np.arange(-0.26, 0.26, STEP), np.arange(-0.34, 0.34, STEP), indexing="ij")
    rho = np.hypot(u - FIELD[0], v - FIELD[1])
    h = np.maximum(height * (1.0 - rho / radius), 0.0)
    p = np.stack([u + BOARD.center[0], v + BOARD.center[1], h], axis=-1).astype(np.float32)
    cos_tilt = 1.0 / np.hypot(1.0, height / radius)
    on = h > 0
    rgb = np.where(on[..., None], np.array(paint) * (0.3 + 0.7 * cos_tilt), WHITE)
    return p, np.clip(rgb, 0, 255).astype(np.uint8)


@pytest.mark.parametrize(("paint", "name"), [((238, 240, 232), "white"), ((128, 128, 128), "grey")])
def test_a_cones_shaded_flanks_keep_its_colour(paint: tuple[int, int, int], name: str) -> None:
    """A white cone 60 mm tall on a 28 mm radius: its flanks (65 degrees) get 59 % of the light
    the board gets, grey by brightness alone. Corrected for the flanks' tilt, it is white (and
    a grey cone stays grey)."""
    cloud, rgb = _cone_scene(0.06, 0.028, paint)
    det = detect(cloud, BOARD, rgb=rgb)
    assert det.status == "ok" and len(det.objects) == 1, det
    assert det.objects[0].colour == name


def test_lit_share_of_flat_and_tilted_faces_and_steps() -> None:
    yy, xx = np.mgrid[0:20, 0:20] * 0.002
    flat = np.stack([xx, yy, np.zeros_like(xx)]).astype(np.float32)
    rows, cols = np.full(5, 10), np.arange(8, 13)
    assert np.allclose(lit_share(flat, rows, cols), 1.0)
    tilted = np.stack([xx, yy, np.tan(np.radians(60)) * xx]).astype(np.float32)  # 60 degrees
    assert np.allclose(lit_share(tilted, rows, cols), 0.75, atol=1e-3)
    step = flat.copy()
    step[2, :, 11:] = 0.04  # a flat top 40 mm above a flat board
    lit = lit_share(step, rows, cols)  # pixels within NORMAL_STEP of the step measure no face
    near = np.abs(cols + 0.5 - 11) < NORMAL_STEP
    assert np.all(np.isnan(lit[near])) and np.allclose(lit[~near], 1.0) and (~near).any()
    tilted[2] = np.nan
    assert np.all(np.isnan(lit_share(tilted, rows, cols)))  # no depth: no normal


def test_a_sparse_tip_is_as_high_as_its_highest_part() -> None:
    """The seen half of a black cone's upper part (86 mm tall, 28.7 mm radius; its far side and
    lower flanks are depth holes): 300 points, 1 mm noise. Neither a cone nor a cap fit is accepted;
    its top band spreads over 10 mm, so it is no flat face and its median (13.5 mm short) is not
    the height."""
    height, radius = 0.086, 0.0287
    rng = np.random.default_rng(0)
    rho, ang = radius * np.sqrt(rng.random(1200)), np.pi * rng.random(1200)
    z = height * (1 - rho / radius)
    seen = z > 0.04
    rho, ang, z = rho[seen][:300], ang[seen][:300], z[seen][:300] + rng.normal(0, 0.001, 300)
    b = np.stack([rho * np.cos(ang), rho * np.sin(ang), z]).astype(np.float32)
    est = estimate_object(ObjectPoints(b), 0.0011, DEFAULT_PARAMS)
    assert abs(est.height - height) < 0.006


def test_an_object_seen_only_in_scattered_pixels_is_answered() -> None:
    """A black cone whose depth survives in scattered single pixels (10 %): no piece of it holds
    two seed hits. The detector answers (it raised IndexError) and reports no object of specks."""
    u, v = np.meshgrid(np.arange(-0.26, 0.26, STEP), np.arange(-0.34, 0.34, STEP), indexing="ij")
    z = np.maximum(0.086 * (1 - np.hypot(u - FIELD[0], v - FIELD[1]) / 0.0287), 0.0)
    rng = np.random.default_rng(0)
    on = z > 0
    p = np.stack([u + BOARD.center[0], v + BOARD.center[1], z + on * rng.normal(0, 0.001, z.shape)], axis=-1)
    p[on & (rng.random(z.shape) > 0.1)] = np.nan
    rgb = np.where(on[..., None], np.array([25, 25, 28]), WHITE).astype(np.uint8)
    det = detect(p.astype(np.float32), BOARD, rgb=rgb)
    assert det.status == "no_object" and det.objects == []


def _surface(height_of, half_seen: bool, seed: int = 0) -> np.ndarray:  # type: ignore[no-untyped-def]
    """(3, n) points of a surface ``h = height_of(r)`` around (0.02, -0.01) on a 1.5 mm grid, with
    1 mm depth noise; ``half_seen``: only the half x > 0.005 (the rest in a shadow)."""
    u, v = np.meshgrid(np.arange(-0.05, 0.05, 0.0015), np.arange(-0.05, 0.05, 0.0015))
    r = np.hypot(u, v)
    h = height_of(r)
    keep = (h > 0.002) & ((u > 0.005) if half_seen else True)
    h = h + np.random.default_rng(seed).normal(scale=0.001, size=h.shape)
    return np.stack([u[keep] + 0.02, v[keep] - 0.01, h[keep]]).astype(np.float32)


@pytest.mark.parametrize("half_seen", [False, True])
def test_a_cone_is_placed_from_its_flanks_when_its_base_is_half_unseen(half_seen: bool) -> None:
    from sofia_detector.objects.caps import fit_cone_apex

    b = _surface(lambda r: np.where(r < 0.03, 0.07 * (1 - r / 0.03), 0.0), half_seen)
    cone = fit_cone_apex(b, 0.001)
    assert cone is not None
    apex_xy, height, base = cone
    assert np.allclose(apex_xy, (0.02, -0.01), atol=0.0015)
    assert height == pytest.approx(0.07, abs=0.003) and base == pytest.approx(0.03, abs=0.002)


@pytest.mark.parametrize(
    "height_of",
    [
        lambda r: np.where(r < 0.03, np.sqrt(np.maximum(0.03**2 - r**2, 0.0)), 0.0),  # a ball's cap
        lambda r: np.where(r < 0.03, 0.06, 0.0),  # a flat top
        lambda r: np.where(r < 0.012, 0.16, np.where(r < 0.035, 0.16 - 2 * (r - 0.012), 0.0)),  # shoulder
    ],
    ids=["ball", "flat", "bottle"],
)
def test_caps_tops_and_shoulders_are_no_cones(height_of) -> None:  # type: ignore[no-untyped-def]
    from sofia_detector.objects.caps import fit_cone_apex

    assert fit_cone_apex(_surface(height_of, True), 0.001) is None
