"""A tiny golden file pins the PointCloud2 wire format (written once by rosbags' serialize_cdr)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sofia_schemas import pointcloud

GOLDEN = Path(__file__).parent / "data" / "pointcloud2_2x2_xyzrgb.cdr"
POINTS = np.array(
    [[[0.5, -0.25, 1.0], [0.0, 0.125, 2.0]], [[np.nan] * 3, [1.5, 2.5, -3.5]]], dtype=np.float32
)
RGB = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [10, 20, 30]]], dtype=np.uint8)
STAMP_NS = 1_700_000_000_123_456_789


def test_encode_matches_golden() -> None:
    cdr = pointcloud.encode_points(POINTS, stamp_ns=STAMP_NS, frame_id="panda_link0", rgb=RGB)
    assert bytes(cdr) == GOLDEN.read_bytes()


def test_decode_golden() -> None:
    cloud = pointcloud.decode(GOLDEN.read_bytes())
    assert (cloud.stamp_ns, cloud.frame_id, cloud.shape, cloud.is_dense) == (
        STAMP_NS,
        "panda_link0",
        (2, 2),
        False,
    )
    np.testing.assert_array_equal(cloud.xyz(), POINTS)
    rgb = cloud.rgb()
    assert rgb is not None
    np.testing.assert_array_equal(rgb, RGB)
