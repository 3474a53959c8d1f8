"""Shared fixtures of the calibrator tests: the lab's real samples, shipped in ``data/lab``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

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
