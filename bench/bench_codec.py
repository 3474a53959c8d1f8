"""PointCloud2 CDR codec on a 640x480 xyz+rgb cloud, against a plain memory copy of the same bytes.

Run: .venv/bin/python bench/bench_codec.py

Ours: ``sofia_schemas.pointcloud`` (encode_points from numpy arrays; decode to zero-copy views).
Baseline: ``np.copyto`` of a buffer as large as the message (the cost of touching every byte
once). Second reference: rosbags ``serialize_cdr``/``deserialize_cdr`` of the same message.
Each row is the median of repeated runs, measured in this process.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np
from rosbags.typesys import Stores, get_typestore
from sofia_schemas import pointcloud

H, W = 480, 640
PC2 = "sensor_msgs/msg/PointCloud2"


def median_s(fn: Callable[[], object], repeat: int = 30, number: int = 5) -> float:
    """Median seconds per call over ``repeat`` batches of ``number`` calls (after one warm-up)."""
    fn()
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        runs.append((time.perf_counter() - t0) / number)
    return statistics.median(runs)


def d435_like_cloud(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) float32 camera-frame points (a plane at 0.6 m, 3 % NaN) and (H, W, 3) uint8 colours."""
    v, u = np.mgrid[0:H, 0:W]
    z = 0.6 + 0.0005 * rng.standard_normal((H, W))
    points = np.stack([(u - W / 2) / 615 * z, (v - H / 2) / 615 * z, z], axis=-1).astype(np.float32)
    points[rng.random((H, W)) < 0.03] = np.nan
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    return points, rgb


def main() -> None:
    rng = np.random.default_rng(0)
    points, rgb = d435_like_cloud(rng)
    cdr = bytes(pointcloud.encode_points(points, stamp_ns=1, frame_id="camera_color_optical_frame", rgb=rgb))
    src = np.frombuffer(cdr, np.uint8)
    dst = np.empty_like(src)

    ts = get_typestore(Stores.ROS2_HUMBLE)
    ros_msg = ts.deserialize_cdr(cdr, PC2)

    def decode_views() -> object:
        cloud = pointcloud.decode(cdr)
        return cloud.xyz(), cloud.rgb()

    def decode_to_arrays() -> object:
        cloud = pointcloud.decode(cdr)
        return np.ascontiguousarray(cloud.xyz()), np.ascontiguousarray(cloud.rgb())

    copy = median_s(lambda: np.copyto(dst, src))
    copy_bytes = median_s(lambda: bytes(bytearray(cdr)))
    rows = [
        ("encode_points (numpy -> CDR)", median_s(lambda: pointcloud.encode_points(
            points, stamp_ns=1, frame_id="camera_color_optical_frame", rgb=rgb))),
        ("encode (PointCloud2 -> CDR)", median_s(lambda: pointcloud.encode(pointcloud.decode(cdr)))),
        ("decode + xyz/rgb views (zero-copy)", median_s(decode_views)),
        ("decode + np.ascontiguousarray of the views", median_s(decode_to_arrays)),
        ("rosbags serialize_cdr (reference)", median_s(lambda: ts.serialize_cdr(ros_msg, PC2))),
        ("rosbags deserialize_cdr (reference)", median_s(lambda: ts.deserialize_cdr(cdr, PC2))),
    ]  # fmt: skip

    print(f"640x480 xyz+rgb PointCloud2, {len(cdr) / 1e6:.2f} MB of CDR; baseline: np.copyto of the same "
          f"{len(cdr) / 1e6:.2f} MB = {copy * 1e3:.3f} ms (bytes(bytearray) copy: {copy_bytes * 1e3:.3f} ms)\n")  # fmt: skip
    print("| operation | time (ms) | memory copy (ms) | ratio to copy |")
    print("|---|---:|---:|---:|")
    for name, t in rows:
        print(f"| {name} | {t * 1e3:.3f} | {copy * 1e3:.3f} | {t / copy:.2f}x |")


if __name__ == "__main__":
    main()
