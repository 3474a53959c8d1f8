"""``sofia detect FILE...`` as a user runs it: MCAP, PCD (ASCII, binary), PLY, NPY; --json, --plot."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
from sofia_replay import read_truth
from sofia_replay.synth import DEFAULT_T_FLANGE_CAM, write_scene_set

from ..conftest import SOFIA
from .conftest import write_pcl_ascii


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([SOFIA, "detect", *args], capture_output=True, text=True, timeout=120)


def json_records(out: str) -> list[dict]:  # type: ignore[type-arg]
    return [json.loads(line) for line in out.splitlines() if line.startswith("{")]


def _finite(points: np.ndarray) -> np.ndarray:
    p = points.reshape(-1, 3)
    return p[np.isfinite(p).all(axis=1)].astype(np.float64)


@pytest.fixture(scope="module")
def cloud_files(tmp_path_factory, scenes) -> dict[str, Path]:  # type: ignore[no-untyped-def]
    d = tmp_path_factory.mktemp("clouds")
    pts = scenes["cylinder"].points_base
    files = {
        "npy": d / "scene.npy",
        "pcl": d / "pcl_ascii.pcd",
        "pcd_bin": d / "o3d_binary.pcd",
        "ply": d / "scene.ply",
    }
    np.save(files["npy"], pts)
    write_pcl_ascii(files["pcl"], pts)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(_finite(pts)))
    o3d.io.write_point_cloud(str(files["pcd_bin"]), pcd, write_ascii=False)
    o3d.io.write_point_cloud(str(files["ply"]), pcd)
    return files


def test_every_format_finds_the_object(cloud_files: dict[str, Path], scenes) -> None:  # type: ignore[no-untyped-def]
    truth = scenes["cylinder"].objects[0]
    r = run(*map(str, cloud_files.values()), "--json")
    assert r.returncode == 0, r.stderr
    recs = json_records(r.stdout)
    assert [Path(x["file"]).name for x in recs] == [p.name for p in cloud_files.values()]
    for rec in recs:
        assert rec["index"] == 0 and rec["status"] == "ok" and len(rec["objects"]) == 1, rec
        obj = rec["objects"][0]
        assert set(obj) >= {
            "center",
            "centroid",
            "extents",
            "yaw",
            "field",
            "allowed",
            "n_points",
            "confidence",
        }
        assert np.linalg.norm(np.array(obj["center"]) - truth.center) < 0.005, rec["file"]
        assert tuple(obj["field"]) == truth.field and obj["allowed"] is True
        assert rec["timings_ms"]["total_ms"] > 0


def test_mcap_every_cloud_against_truth(tmp_path: Path) -> None:
    path = tmp_path / "set.mcap"
    write_scene_set(path, kind="mixed", n=4, seed=5, frames="base")
    truth = read_truth(path)
    r = run(str(path), "--json")
    assert r.returncode == 0, r.stderr
    recs = json_records(r.stdout)
    assert [x["index"] for x in recs] == [0, 1, 2, 3]
    for rec, frame in zip(recs, truth["frames"], strict=True):
        assert rec["stamp_ns"] == frame["stamp_ns"]
        assert len(rec["objects"]) == len(frame["objects"])
        for t in frame["objects"]:
            err = min(np.linalg.norm(np.array(o["center"]) - t["center"]) for o in rec["objects"])
            assert err < 0.005


def test_camera_frame_mcap_with_a_transform_file(tmp_path: Path) -> None:
    path = tmp_path / "camera.mcap"
    write_scene_set(path, kind="one", n=2, seed=9, frames="camera")
    tf = tmp_path / "T_flange_cam.yaml"
    tf.write_text(f"matrix: {DEFAULT_T_FLANGE_CAM.tolist()}\n")
    assert run(str(path)).returncode == 1  # camera clouds only, no transform: says so
    r = run(str(path), "--json", "--transform", str(tf))
    assert r.returncode == 0, r.stderr
    recs = json_records(r.stdout)
    truth = read_truth(path)
    assert len(recs) == 2
    for rec, frame in zip(recs, truth["frames"], strict=True):
        assert rec["transform"] == f"file {tf}"
        assert np.linalg.norm(np.array(rec["objects"][0]["center"]) - frame["objects"][0]["center"]) < 0.005


def test_a_bad_transform_file_gets_one_line_naming_it(cloud_files: dict[str, Path], tmp_path: Path) -> None:
    tf = tmp_path / "T_flange_cam.yaml"
    tf.write_text("matrix: [[1, 0], [0, 1]]\n")
    r = run(str(cloud_files["npy"]), "--transform", str(tf))
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith(f"sofia detect: error: {tf}: ") and "shape (4, 4)" in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1


def test_human_output_and_plot(cloud_files: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "plot.png"
    r = run(str(cloud_files["npy"]), "--plot", str(out))
    assert r.returncode == 0, r.stderr
    assert "ok: 1 object(s)" in r.stdout and "allowed: centre (" in r.stdout
    assert (
        out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and 20_000 < out.stat().st_size < 300_000
    )  # a height map, not 60k dots


def test_board_file_is_used(cloud_files: dict[str, Path], tmp_path: Path) -> None:
    board = tmp_path / "board.yaml"
    board.write_text("center: [0.5, 0.0]\nallowed: [[0, 0]]\n")  # field (1, 3) is no longer red
    rec = json_records(run(str(cloud_files["npy"]), "--json", "--board", str(board)).stdout)[0]
    assert rec["objects"][0]["allowed"] is False


BAD_FILES = [
    ("garbage.pcd", b"this is not a point cloud", "not a PCD file"),
    ("garbage.npy", b"\x00\x01\x02", "not a NumPy .npy array"),
    ("garbage.mcap", b"not mcap at all", "not a readable MCAP file"),
    ("cloud.xyz", b"1 2 3", "unknown cloud format '.xyz'"),
    ("wrong_shape.npy", None, "expected shape (N, 3) or (H, W, 3), got (10, 2)"),
    ("missing.pcd", False, "missing.pcd: no such file"),
]


def test_bad_files_are_reported_and_good_ones_still_processed(
    tmp_path: Path, cloud_files: dict[str, Path]
) -> None:
    paths = []
    for name, content, _ in BAD_FILES:
        path = tmp_path / name
        if content is None:
            np.save(path, np.zeros((10, 2)))
        elif content:
            path.write_bytes(content)
        paths.append(str(path))
    r = run(*paths, str(cloud_files["npy"]))
    assert r.returncode == 2  # bad input files: the usage/input exit code
    for _, _, needle in BAD_FILES:
        assert needle in r.stderr, r.stderr
    assert r.stdout.count("ok: 1 object(s)") == 1  # the good file is still processed
    assert "Traceback" not in r.stderr
