"""Where the board lies when part of its outline is not its edge: a side of the board top cut short
by missing depth (the second imager's blind band on the image's left), the image border or the
fingers does not say where the board ends; only a drop to the table beside it does."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector import detect
from sofia_detector.board.outline import fit_outline
from sofia_replay.synth.realism import bench_frame
from sofia_replay.synth.scene import BOARD_MARGIN
from sofia_schemas import Board
from sofia_schemas.transforms import invert

BOARD = Board.default()
EXTENT = np.array(BOARD.extent)
MAX_RIM = 0.05
MAX_YAW = 0.105


def test_a_board_edge_lost_in_missing_depth_does_not_move_the_board_onto_the_clutter() -> None:
    # bench_detector_real.py's bottle-000: the board edge on the image's left lies in the band without depth,
    # the clutter box stands against the opposite edge
    f = bench_frame(BOARD, "bottle", 0)
    T_board_base = invert(f.T_base_board)
    p = f.points_base.reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    p_board = p @ T_board_base[:3, :3].T + T_board_base[:3, 3]
    half = EXTENT / 2 + BOARD_MARGIN
    top = (np.abs(p_board[:, 2]) < 0.005) & np.all(np.abs(p_board[:, :2]) < half, axis=1)
    assert p_board[top, 1].min() > -half[1] + 0.03, "the board's -y edge is out of sight"
    assert p_board[top, 1].max() > half[1] - 0.005, "its +y edge is seen"
    clutter = (p_board[:, 1] > half[1]) & (p_board[:, 2] > 0.02)
    assert np.count_nonzero(clutter) > 500, "the clutter box stands beyond the +y edge"

    det = detect(f.points_base, f.board, rgb=f.rgb)
    board_err = np.linalg.norm(np.array(det.board_center) - f.T_base_board[:3, 3])
    assert board_err < 0.01, f"board centre off by {board_err * 1e3:.1f} mm"
    assert len(det.objects) == 1, [(o.center, o.field, o.confidence) for o in det.objects]
    assert np.linalg.norm(np.array(det.objects[0].center) - f.objects[0].center) < 0.01
    assert "not fully seen" in det.detail


def _outline(
    center: np.ndarray, rim: float, cuts: dict[int, float], step: float = 0.005
) -> tuple[np.ndarray, np.ndarray]:
    """Outline points (k, 2) of the top of a board of :data:`EXTENT` fields and ``rim`` centred at
    ``center`` (2,), with the side ``s`` of ``cuts`` (0: -x, 1: -y, 2: +x, 3: +y) cut short at the
    given coordinate, and (k, 2) the drop beside each: outwards on the board's edges, none along
    the cuts but near their ends, where the table beyond the neighbouring edge is close."""
    lo, hi = center - EXTENT / 2 - rim, center + EXTENT / 2 + rim
    bounds = np.array([lo, hi])  # (side lo/hi, axis)
    cut = np.zeros((2, 2), dtype=bool)
    for s, at in cuts.items():
        bounds[s // 2, s % 2] = at
        cut[s // 2, s % 2] = True
    points, drops = [], []
    for axis in (0, 1):
        other = 1 - axis
        t = np.arange(bounds[0, other], bounds[1, other] + 1e-9, step)
        for side, sign in ((0, -1.0), (1, 1.0)):
            xy = np.empty((t.size, 2))
            xy[:, axis], xy[:, other] = bounds[side, axis], t
            drop = np.zeros((t.size, 2))
            if not cut[side, axis]:
                drop[:, axis] = sign
            else:  # the edges it meets drop along the cut, within a centimetre of their corners
                for end, end_sign in ((0, -1.0), (1, 1.0)):
                    if not cut[end, other]:
                        drop[np.abs(t - bounds[end, other]) < 0.01, other] = end_sign
            points.append(xy)
            drops.append(drop)
    return np.concatenate(points), np.concatenate(drops)


@pytest.mark.parametrize("side", [0, 1, 2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_centre_comes_from_the_edge_that_is_seen_and_the_rim_of_the_other_axis(
    side: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    center = rng.uniform(-0.04, 0.04, 2)
    rim = float(rng.uniform(0.015, 0.04))
    axis, sign = side % 2, (-1.0 if side < 2 else 1.0)
    # cut short by 2.5 cm to 1 cm more than both rims: what is seen is as large as a whole board
    # with a narrower rim would be
    edge = center[axis] + sign * (EXTENT[axis] / 2 + rim)
    xy, drop = _outline(center, rim, {side: edge - sign * rng.uniform(0.025, 2 * rim + 0.01)})
    out = fit_outline(xy, tuple(EXTENT), MAX_YAW, MAX_RIM, drop)
    assert np.allclose(out.center, center, atol=0.002), (out.center, center)
    assert out.complete[axis] is False and out.complete[1 - axis] is True
    # every outline point taken for an edge: the midpoint of what is seen
    seen = fit_outline(xy, tuple(EXTENT), MAX_YAW, MAX_RIM)
    assert abs(seen.center[axis] - center[axis]) > 0.01


def test_with_no_axis_complete_the_rim_is_half_the_widest() -> None:
    center, rim = np.array([0.03, -0.02]), 0.02
    # the +x and +y sides cut short (the board runs off two image borders)
    xy, drop = _outline(center, rim, {2: center[0] + 0.15, 3: center[1] + 0.2})
    out = fit_outline(xy, tuple(EXTENT), MAX_YAW, MAX_RIM, drop)
    assert out.complete == (False, False)
    # the -x and -y edges are seen: the centre lies max_rim / 2 beyond the fields inside them
    assert np.allclose(out.center, center + (MAX_RIM / 2 - rim), atol=0.002), (out.center, center)


def test_a_side_cut_short_on_both_ends_keeps_the_midpoint_of_a_plausible_size() -> None:
    center, rim = np.array([0.01, 0.02]), 0.02
    xy, drop = _outline(center, rim, {1: center[1] - 0.29, 3: center[1] + 0.31})
    out = fit_outline(xy, tuple(EXTENT), MAX_YAW, MAX_RIM, drop)
    assert out.complete == (True, False)
    assert abs(out.center[0] - center[0]) < 0.002
    assert abs(out.center[1] - (center[1] + 0.01)) < 0.002
