"""Organized clouds whatever the file format, clear errors for clouds that cannot be right, and
detect queries that select objects by colour."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from sofia_detector import detect
from sofia_detector.readers import iter_file_clouds, pcd_grid
from sofia_detector.selection import BadSelection, select, split_selection
from sofia_schemas import Board
from sofia_schemas.messages import DetectedObject, Detection

from ..conftest import SOFIA
from .conftest import write_pcl_ascii


def test_pcd_header_grid() -> None:
    assert pcd_grid(b"FIELDS x y z\nWIDTH 640\nHEIGHT 480\nDATA binary\n") == (480, 640)
    assert pcd_grid(b"FIELDS x y z\nWIDTH 1000\nHEIGHT 1\nDATA ascii\n") == (1, 1000)


def test_organized_pcd_is_read_organized_and_matches_npy(tmp_path: Path, scenes, board: Board) -> None:  # type: ignore[no-untyped-def]
    pts = scenes["cylinder"].points_base
    write_pcl_ascii(tmp_path / "c.pcd", pts)
    np.save(tmp_path / "c.npy", pts)
    (pcd,) = iter_file_clouds(tmp_path / "c.pcd", board.frame_id)
    (npy,) = iter_file_clouds(tmp_path / "c.npy", board.frame_id)
    assert pcd.points.shape == npy.points.shape == pts.shape
    a, b = detect(pcd.points, board), detect(npy.points, board)
    assert len(a.objects) == len(b.objects) == 1
    assert np.allclose(a.objects[0].center, b.objects[0].center, atol=1e-4)


def test_empty_millimetre_and_camera_frame_files_are_errors(tmp_path: Path, scenes) -> None:  # type: ignore[no-untyped-def]
    frame = scenes["box"].frame
    np.save(tmp_path / "empty.npy", np.zeros((0, 3), np.float32))
    np.save(tmp_path / "empty_organized.npy", np.zeros((0, 640, 3), np.float32))
    np.save(tmp_path / "mm.npy", frame.points_base * 1000.0)
    np.save(tmp_path / "camera.npy", frame.render.points_cam)
    cases = {
        "empty.npy": "holds no points",
        "empty_organized.npy": "holds no points",
        "mm.npy": "millimetres",
        "camera.npy": "camera-frame cloud",
    }
    r = subprocess.run(
        [SOFIA, "detect", *(str(tmp_path / n) for n in cases)], capture_output=True, text=True, timeout=180
    )
    assert r.returncode == 2, (r.stdout, r.stderr)  # bad input files: the usage/input exit code
    lines = r.stderr.splitlines()
    for name, needle in cases.items():
        assert any(name in line and needle in line for line in lines), (name, r.stderr)
    assert "Traceback" not in r.stderr


def _obj(colour: str | None) -> DetectedObject:
    return DetectedObject(
        center=(0.5, 0.0, 0.02), centroid=(0.5, 0.0, 0.02), extents=(0.04, 0.04, 0.04), yaw=0.0,
        field=(1, 1), allowed=True, n_points=500, confidence=1.0, colour=colour,
    )  # fmt: skip


def test_colour_selection_queries() -> None:
    sel, cloud = split_selection(b'{"colour": "yellow"}')
    assert sel == "yellow" and cloud == b""
    assert split_selection(b"\x00\x01\x00\x00rest") == (None, b"\x00\x01\x00\x00rest")  # a CDR cloud
    assert split_selection(b"{not cdr}") == (None, b"{not cdr}")  # left to the cloud decoder
    det = Detection(stamp_ns=1, frame_id="panda_link0", status="ok", objects=[_obj("green"), _obj("yellow")])
    picked = select(det, sel)
    assert [o.colour for o in picked.objects] == ["yellow"]
    none = select(det, split_selection(b'{"color": "blue"}')[0])
    assert none.status == "no_object" and none.objects == []


@pytest.mark.parametrize(
    ("payload", "needle"),
    [(b'{"colour": "mauve"}', "not one of"), (b'{"size": 3}', "expected"), (b"{}", "expected")],
)
def test_bad_selections_are_named(payload: bytes, needle: str) -> None:
    with pytest.raises(BadSelection, match=needle):
        split_selection(payload)


def test_old_detected_object_payloads_still_parse() -> None:
    old = (
        '{"center": [0.5, 0, 0.02], "centroid": [0.5, 0, 0.02], "extents": [0.04, 0.04, 0.04], '
        '"yaw": 0, "field": [1, 1], "allowed": true, "n_points": 10, "confidence": 1.0}'
    )
    obj = DetectedObject.model_validate_json(old)
    assert obj.colour is None and obj.visibility == 1.0 and obj.truncated == ()
