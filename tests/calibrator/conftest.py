"""Shared fixtures and helpers of the calibrator tests: the lab's real samples (``data/lab``), rendered views."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator.fitting.simulate import random_T_flange_cam, views_of

REPO = Path(__file__).resolve().parents[2]
LAB = REPO / "data" / "lab"


@pytest.fixture
def lab_dir() -> Path:
    assert (LAB / "poses.txt").is_file() and (LAB / "tfs.txt").is_file(), f"missing lab samples in {LAB}"
    return LAB


def write_views(tmp_path: Path, images: list, T_base_flange: np.ndarray) -> tuple[list[str], Path]:
    """The rendered views as PNG files and the flange poses (n, 4, 4) as the 'a, b, c, x, y, z' lines
    of ``--euler-poses`` (radians, xyz; millimetres): (image paths, poses file)."""
    import cv2
    from scipy.spatial.transform import Rotation

    names = [str(tmp_path / f"view{i}.png") for i in range(len(images))]
    for name, img in zip(names, images, strict=True):
        cv2.imwrite(name, img)
    rows = np.c_[
        Rotation.from_matrix(T_base_flange[:, :3, :3]).as_euler("xyz"), 1e3 * T_base_flange[:, :3, 3]
    ]
    np.savetxt(tmp_path / "poses.dat", rows, delimiter=",")
    return names, tmp_path / "poses.dat"


def rendered_views(
    n: int,
    seed: int,
    draw: Callable[[np.ndarray], np.ndarray],
    distance: tuple[float, float],
    target_origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """Views of a flat target lying face up at (0.5, 0, 0) in the base frame, its origin
    ``target_origin`` (target frame, m) from that point: (X true T_flange_cam, T_base_flange (n, 4, 4),
    true T_cam_target (n, 4, 4), 8-bit images drawn by ``draw(T_cam_target)`` with pixel noise)."""
    rng = np.random.default_rng(seed)
    X = random_T_flange_cam(rng)
    centre = np.array([0.5, 0.0, 0.0])
    Y = np.eye(4)
    Y[:3, :3] = np.diag([1.0, -1.0, -1.0])  # the target's z into the table: its face up
    Y[:3, 3] = centre - Y[:3, :3] @ np.asarray(target_origin)
    T_base_cam = views_of(centre, n, rng, distance=distance, max_off_axis_deg=35, max_image_offset_deg=8)
    B = np.linalg.inv(T_base_cam) @ Y
    images = [np.clip(draw(b) + rng.normal(0, 3, (480, 640)), 0, 255).astype(np.uint8) for b in B]
    return X, T_base_cam @ np.linalg.inv(X), B, images
