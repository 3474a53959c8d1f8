"""Synthetic board scenes rendered once per test session (each takes ~0.15 s)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from sofia_replay.synth import SceneFrame, make_scene, render_scene
from sofia_schemas import Board


@dataclass
class Rendered:
    name: str
    frame: SceneFrame

    @property
    def points_base(self) -> np.ndarray:
        return self.frame.points_base

    @property
    def objects(self) -> list:  # type: ignore[type-arg]
        return self.frame.scene.objects


SCENES = {
    "box": ("one", "box", (0, 0)),
    "cylinder": ("one", "cylinder", (1, 3)),
    "sphere": ("one", "sphere", (2, 2)),
    "empty": ("empty", None, None),
    "nonred": ("nonred", "box", (1, 2)),
    "two": ("two", None, None),
}


@pytest.fixture(scope="session")
def board() -> Board:
    return Board.default()


@pytest.fixture(scope="session")
def scenes(board: Board) -> dict[str, Rendered]:
    out = {}
    for i, (name, (kind, shape, fld)) in enumerate(SCENES.items()):
        rng = np.random.default_rng(100 + i)
        scene = make_scene(board, kind, rng, shape=shape, fld=fld)  # type: ignore[arg-type]
        out[name] = Rendered(name, render_scene(scene, rng))
    return out


def write_pcl_ascii(path: Path, points: np.ndarray) -> None:
    """A PCD file as PCL's ``pcl::io::savePCDFileASCII`` writes it (organized, NaN kept)."""
    h, w = points.shape[:2]
    head = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
        f"COUNT 1 1 1\nWIDTH {w}\nHEIGHT {h}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {h * w}\nDATA ascii\n"
    )
    with path.open("w") as f:
        f.write(head)
        np.savetxt(f, points.reshape(-1, 3), fmt="%.6f")
