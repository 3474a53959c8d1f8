"""Readers of other labs' target data: point clouds (PCD/PLY through Open3D) and flange poses as
Euler angles plus positions, one pose per line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InputMismatch, ParseError


def read_cloud(path: str | Path) -> np.ndarray:
    """(n, 3) points of a PCD or PLY file (Open3D's reader), in the file's unit; NaN rows dropped."""
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise ParseError(path, None, "no such point-cloud file")
    points = np.asarray(o3d.io.read_point_cloud(path).points, dtype=np.float64)
    if points.size == 0:
        raise ParseError(path, None, "no points (not a PCD/PLY file, or an empty cloud)")
    return points[np.isfinite(points).all(axis=1)]


def read_euler_poses(path: str | Path, convention: str = "xyz", length_unit_m: float = 1e-3) -> np.ndarray:
    """(n, 4, 4) T_base_flange, metres, from lines ``a, b, c, x, y, z`` (angles in radians).

    convention: SciPy's Euler sequence of (a, b, c) (lower case extrinsic, upper case intrinsic);
    RegHEC's ``RobotPoses.dat`` (rx, ry, rz then mm, "Euler ZYX") is "xyz" with ``length_unit_m``
    1e-3.
    """
    path = Path(path)
    rows = []
    for i, line in enumerate(Path(path).read_text().splitlines(), start=1):
        parts = [x for x in line.replace(",", " ").split() if x]
        if not parts or parts[0].startswith("#"):
            continue
        if len(parts) != 6:
            raise ParseError(
                path, i, f"expected 6 values (3 angles, 3 positions), got {len(parts)}: {line!r}"
            )
        try:
            rows.append([float(x) for x in parts])
        except ValueError:
            raise ParseError(path, i, f"not a number in {line!r}") from None
    if not rows:
        raise ParseError(path, None, "no poses (the file is empty)")
    a = np.array(rows)
    if not np.isfinite(a).all():
        raise ParseError(path, None, "a pose has a non-finite value")
    T = np.tile(np.eye(4), (len(a), 1, 1))
    T[:, :3, :3] = Rotation.from_euler(convention, a[:, :3]).as_matrix()
    T[:, :3, 3] = a[:, 3:] * length_unit_m
    return T


def read_opencv_pose_pairs(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(T1 (n, 4, 4), T2 (n, 4, 4)) from an OpenCV YAML file of ``frameCount`` and ``T1_i`` /
    ``T2_i`` matrices (handeye_calib_camodocal's TransformPairsInput.yml: robot and marker poses,
    metres), through OpenCV's own FileStorage reader."""
    import cv2

    path = Path(path)
    if not path.is_file():
        raise ParseError(path, None, "no such pose-pair file")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        n = int(fs.getNode("frameCount").real())
        if n <= 0:
            raise ParseError(path, None, "no frameCount (not a pose-pair file)")
        pairs = []
        for i in range(n):
            a, b = (fs.getNode(f"{k}_{i}").mat() for k in ("T1", "T2"))
            if a is None or b is None or a.shape != (4, 4) or b.shape != (4, 4):
                raise ParseError(path, None, f"pair {i}: T1_{i} and T2_{i} must be 4x4 matrices")
            pairs.append((a, b))
    finally:
        fs.release()
    both = np.array(pairs, dtype=np.float64)  # (n, 2, 4, 4)
    return both[:, 0], both[:, 1]


def read_grey_images(paths: list[str]) -> list[np.ndarray]:
    """(h, w) uint8 grey images of image files (PNG, JPEG, ... through OpenCV), one per path."""
    import cv2

    images = []
    for p in paths:
        img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ParseError(Path(p), None, "not an image file OpenCV can read")
        images.append(img)
    return images


def read_camera_matrix(text: str) -> np.ndarray:
    """(3, 3) camera matrix K from ``"fx fy cx cy"`` (pixels) or a YAML/JSON file holding ``K`` or
    ``k`` (9 numbers or 3x3, as a ROS CameraInfo) or ``fx``, ``fy``, ``cx``, ``cy``."""
    from sofia_schemas.files import FileContentError, load_json_or_yaml

    parts = text.replace(",", " ").split()
    try:
        if len(parts) == 4:
            fx, fy, cx, cy = (float(v) for v in parts)
        else:
            data = load_json_or_yaml(Path(text))
            key = next((k for k in ("K", "k", "camera_matrix") if isinstance(data, dict) and k in data), None)
            if key is not None:
                K = np.asarray(data[key], dtype=np.float64).reshape(3, 3)
                fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
            else:
                fx, fy, cx, cy = (float(data[k]) for k in ("fx", "fy", "cx", "cy"))
    except (ValueError, OSError, FileContentError, KeyError, TypeError) as e:
        raise ParseError(
            Path(text), None, f"not 'fx fy cx cy' nor a file with K or fx, fy, cx, cy: {e}"
        ) from None
    if not all(np.isfinite([fx, fy, cx, cy])) or fx <= 0 or fy <= 0:
        raise ParseError(Path(text), None, f"focal lengths must be positive, got fx {fx}, fy {fy}")
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def read_depth_clouds(paths: list[str], K: np.ndarray, unit_m: float = 1e-3) -> list[np.ndarray]:
    """Organized clouds (h, w, 3), camera optical frame, metres (NaN where the depth is 0), of depth
    images (16-bit PNG or any single-channel image OpenCV reads, ``unit_m`` metres per unit, each
    registered to its colour image) back-projected through the camera matrix K (3, 3)."""
    import cv2

    if not 0 < unit_m < 1:
        raise InputMismatch(f"the depth unit must be in (0, 1) metres, got {unit_m}")
    clouds = []
    for p in paths:
        depth = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if depth is None or depth.ndim != 2:
            raise ParseError(Path(p), None, "not a single-channel depth image OpenCV can read")
        z = depth.astype(np.float64) * unit_m
        z[z <= 0] = np.nan
        v, u = np.mgrid[0 : z.shape[0], 0 : z.shape[1]]
        rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(z.shape)], axis=-1)
        clouds.append(rays * z[..., None])
    return clouds
