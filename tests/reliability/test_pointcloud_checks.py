"""Loose PointCloud2s sent to the running detector get an error reply naming what is wrong: x, y and
z at one offset, a FLOAT64 x overlapping y, a zero count, 1 MB of trailing garbage."""

from __future__ import annotations

import numpy as np
import pytest
import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.client import query
from sofia_schemas import Keys, pointcloud
from sofia_schemas.messages import ErrorReply
from sofia_schemas.pointcloud import FLOAT32, FLOAT64, PointField

from .conftest import Service


def _cdr(fields: tuple[PointField, ...], point_step: int = 12, n: int = 4) -> bytes:
    """A CDR PointCloud2 with the given fields, written field by field (no checks on the way)."""
    head = pointcloud._header_bytes(
        1, "panda_link0", 1, n, fields, point_step, point_step * n, point_step * n
    )
    return head + bytes(point_step * n) + b"\x01"


VALID = bytes(pointcloud.encode_points(np.zeros((4, 3)), stamp_ns=1, frame_id="panda_link0"))
CASES = {
    "same offset": (_cdr((PointField("x", 0, FLOAT32), PointField("y", 0, FLOAT32), PointField("z", 0, FLOAT32))),
                    "'x' (bytes up to 4) and 'y' (from byte 0) overlap"),
    "float64 x over y": (_cdr((PointField("x", 0, FLOAT64), PointField("y", 4, FLOAT32), PointField("z", 8, FLOAT32))),
                         "'x' (bytes up to 8) and 'y' (from byte 4) overlap"),
    "count 0": (_cdr((PointField("x", 0, FLOAT32), PointField("y", 4, FLOAT32), PointField("z", 8, FLOAT32, 0))),
                "'z' has count 0"),
    "trailing garbage": (VALID + b"\xee" * 1_000_000, "has 1000000 bytes after its last field"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(CASES))
def test_detector_refuses_loose_clouds(detector: Service, module_robot: str, case: str) -> None:
    payload, expected = CASES[case]
    with zenoh.open(zenoh_config()) as session:
        (reply,) = query(session, Keys(module_robot).detect, payload, timeout=30)
    assert reply.err is not None, f"{case}: accepted"
    err = ErrorReply.model_validate_json(reply.err.payload.to_bytes())
    assert err.error == "SizeMismatch" and expected in err.message, err.message
