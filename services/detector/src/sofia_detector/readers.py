"""Point clouds from files: MCAP recordings, PCD (ASCII or binary), PLY and NumPy ``.npy``."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sofia_replay import iter_clouds, iter_flange_poses
from sofia_replay.errors import RecordingError
from sofia_schemas.keys import TOPIC_FLANGE_POSE, TOPIC_POINTS

from .errors import TransformUnavailable, UnreadableFile
from .frames import FlangeHistory, points_to_base

SUFFIXES = (".mcap", ".pcd", ".ply", ".npy")


@dataclass(frozen=True)
class FileCloud:
    """One cloud of a file: points (N, 3) or (H, W, 3) in the board's frame and their colours (same
    shape, uint8) when the file has them; ``index`` counts from 0; ``transform`` names the
    ``T_flange_cam`` that mapped a camera-frame cloud."""

    index: int
    points: np.ndarray
    stamp_ns: int
    source: str
    transform: str | None = None
    rgb: np.ndarray | None = None


def pcd_grid(head: bytes) -> tuple[int, int]:
    """(HEIGHT, WIDTH) of a PCD header ((1, 0) when absent)."""
    dims = dict(re.findall(rb"^(WIDTH|HEIGHT)[ \t]+(\d+)\s*$", head.split(b"\nDATA")[0], re.MULTILINE))
    return int(dims.get(b"HEIGHT", 1)), int(dims.get(b"WIDTH", 0))


def _open3d_points(path: Path, magic: bytes) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (N, 3), or (H, W, 3) for an organized PCD (HEIGHT > 1), and colours or None."""
    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)  # its warnings: our errors say it
    with path.open("rb") as f:
        head = f.read(4096)
    if magic not in head:
        raise UnreadableFile(path, f"not a {path.suffix[1:].upper()} file (no {magic.decode()!r} header)")
    pcd = o3d.io.read_point_cloud(path, remove_nan_points=False, remove_infinite_points=False)
    points = np.asarray(pcd.points)
    if points.shape[0] == 0 and b"POINTS 0" not in head and b"vertex 0" not in head:
        raise UnreadableFile(path, "Open3D read no points from it (corrupt or unsupported fields)")
    rgb = np.clip(np.asarray(pcd.colors) * 255.0 + 0.5, 0, 255).astype(np.uint8) if pcd.has_colors() else None
    h, w = pcd_grid(head) if magic == b"FIELDS" else (1, 0)
    if h > 1 and h * w == points.shape[0]:  # organized (PCL-style): keep the pixel grid
        points = points.reshape(h, w, 3)
        rgb = None if rgb is None else rgb.reshape(h, w, 3)
    return points, rgb


def _npy_points(path: Path) -> np.ndarray:
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as e:
        raise UnreadableFile(path, f"not a NumPy .npy array: {e}") from None
    if arr.dtype.names and {"x", "y", "z"} <= set(arr.dtype.names):
        arr = np.stack([arr["x"], arr["y"], arr["z"]], axis=-1)
    if arr.size == 0:
        raise UnreadableFile(path, f"holds no points (an empty array of shape {arr.shape})")
    return arr


def iter_file_clouds(
    path: str | Path, frame_id: str, T_flange_cam: np.ndarray | None = None, transform_name: str | None = None
) -> Iterator[FileCloud]:
    """Every cloud of ``path``.

    ``.pcd``/``.ply``/``.npy`` hold one cloud, taken to be in ``frame_id``. ``.mcap``: every
    PointCloud2 on the base-frame topic (``/pc_glob``, whatever its frame_id) or in ``frame_id``;
    clouds in another frame (the camera) are mapped into ``frame_id`` with the recorded flange
    pose at their stamp and ``T_flange_cam`` (4, 4) when given, and skipped otherwise. Raises UnreadableFile for missing or malformed files.
    """
    path = Path(path)
    if not path.is_file():
        raise UnreadableFile(path, "no such file")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise UnreadableFile(path, f"unknown cloud format {suffix!r}; expected one of {SUFFIXES}")
    if suffix == ".npy":
        yield FileCloud(0, _npy_points(path), 0, str(path))
        return
    if suffix in (".pcd", ".ply"):
        points, rgb = _open3d_points(path, b"FIELDS" if suffix == ".pcd" else b"ply")
        if points.shape[0] == 0:
            raise UnreadableFile(path, "holds no points")
        yield FileCloud(0, points, 0, str(path), rgb=rgb)
        return
    try:
        yield from _mcap_clouds(path, frame_id, T_flange_cam, transform_name)
    except RecordingError as e:
        raise UnreadableFile(path, str(e)) from None


def _mcap_clouds(
    path: Path, frame_id: str, T_flange_cam: np.ndarray | None, transform_name: str | None
) -> Iterator[FileCloud]:
    flange: FlangeHistory | None = None
    index = 0
    for topic, _log_ns, cloud in iter_clouds(path):
        points, transform = cloud.xyz(), None
        if topic != TOPIC_POINTS and cloud.frame_id not in (frame_id, ""):  # a camera-frame cloud
            if T_flange_cam is None:
                continue
            if flange is None:
                flange = FlangeHistory(maxlen=1_000_000)
                for stamp_ns, pose in iter_flange_poses(path, TOPIC_FLANGE_POSE):
                    flange.add(pose.stamp_ns or stamp_ns, pose.matrix())
            try:
                points = points_to_base(points, flange.at(cloud.stamp_ns) @ T_flange_cam)
            except TransformUnavailable:
                continue
            transform = transform_name
        yield FileCloud(index, points, cloud.stamp_ns, f"{path}:{topic}", transform, cloud.rgb())
        index += 1
