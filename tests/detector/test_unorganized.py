"""Unorganized clouds (N x 3, as Open3D writes a D435's cloud without its NaN points): flying pixels,
dark objects cut into pieces and colours, without the pixel grid."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_detector import detect
from sofia_detector.segment.unorganized import dense
from sofia_replay.synth.realism import RealFrame, bench_frame
from sofia_schemas import Board

BOARD = Board.default()


def _bench_scene(category: str, k: int) -> RealFrame:
    """bench_detector_real's scene ``<category>-<k>``."""
    return bench_frame(BOARD, category, k)


def _flat(f: RealFrame) -> tuple[np.ndarray, np.ndarray]:
    """The frame's points and colours without the missing points, shuffled: (n, 3), (n, 3)."""
    pts, rgb = f.points_base.reshape(-1, 3), f.rgb.reshape(-1, 3)
    ok = np.flatnonzero(np.isfinite(pts).all(axis=1))
    ok = ok[np.random.default_rng(0).permutation(ok.size)]
    return pts[ok], rgb[ok]


def _near(det, frame: RealFrame) -> list[float]:  # type: ignore[no-untyped-def]
    """For each detected object, the distance (mm) to the nearest true object's centre."""
    centres = np.array([o.center for o in frame.objects])
    return [float(np.min(np.linalg.norm(centres - np.array(d.center), axis=1))) * 1e3 for d in det.objects]


def test_flying_pixels_are_sparse_in_3d_and_dropped() -> None:
    """A surface sampled at a D435's pixel spacing keeps its points; points spread along rays
    between two surfaces (flying pixels) have no neighbours in their voxel."""
    rng = np.random.default_rng(3)
    g = np.arange(0, 0.05, 0.0015)
    x, y = np.meshgrid(g, g)
    surface = np.vstack([x.ravel(), y.ravel(), np.full(x.size, 0.04)])
    # one flying pixel per pixel of the edge, each at its own depth between the two surfaces
    flying = np.vstack([g, np.full(g.size, 0.051), rng.uniform(0.0, 0.04, g.size)])
    keep = dense(np.hstack([surface, flying]))
    assert keep[: surface.shape[1]].mean() > 0.97
    assert keep[surface.shape[1] :].mean() < 0.2


@pytest.mark.parametrize("scene", [("cone", 4), ("occluded", 5)])
def test_the_fingers_flying_pixels_are_no_object(scene: tuple[str, int]) -> None:
    """The fingers' flying-pixel sheets over the board gave a 19 cm tall object at confidence 1.0
    in these scenes once the pixel grid was gone; now only the true object is found."""
    f = _bench_scene(*scene)
    pts, rgb = _flat(f)
    det = detect(pts, f.board, rgb=rgb)
    assert len(det.objects) == len(f.objects), det.objects
    assert max(_near(det, f)) < 5.0
    assert all(o.extents[2] < 0.15 for o in det.objects)


def test_a_dark_object_cut_by_missing_depth_is_one_object_with_its_colour() -> None:
    """A black box whose depth holes split it: its pieces are joined through the cells where the
    cloud has no point at all (it was two objects), and it is named black."""
    f = _bench_scene("dark", 5)
    pts, rgb = _flat(f)
    det = detect(pts, f.board, rgb=rgb)
    assert len(det.objects) == 1, det.objects
    assert _near(det, f)[0] < 5.0
    assert det.objects[0].colour == f.objects[0].colour == "black"


def test_pieces_of_different_colours_stay_apart() -> None:
    """The three-colour scenes' objects, flattened: each found once, each named by its colour."""
    f = _bench_scene("three-colour", 1)
    pts, rgb = _flat(f)
    det = detect(pts, f.board, rgb=rgb)
    assert len(det.objects) == len(f.objects) >= 3
    for o in f.objects:
        d = min(det.objects, key=lambda d: np.linalg.norm(np.array(d.center) - o.center))
        assert np.linalg.norm(np.array(d.center) - o.center) < 0.005
        assert d.colour == o.colour


def test_without_the_pixel_grid_the_confidence_stays_below_0_9() -> None:
    """An unorganized cloud cannot tell the image border or an occluder: a bottle cut by the image
    border is reported whole-looking (its visible part), so no object of such a cloud claims the
    >= 0.9 (within 5 mm) confidence, while the same cloud organized says it is truncated."""
    f = _bench_scene("edge-cut", 11)
    pts, rgb = _flat(f)
    flat = detect(pts, f.board, rgb=rgb)
    grid = detect(f.points_base, f.board, rgb=f.rgb)
    assert flat.objects and all(o.confidence <= 0.85 for o in flat.objects)
    assert all(o.truncated == () for o in flat.objects)
    assert any("image_edge" in o.truncated and o.confidence < 0.5 for o in grid.objects)
