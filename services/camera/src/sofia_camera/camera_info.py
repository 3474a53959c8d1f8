"""``sensor_msgs/msg/CameraInfo`` of the colour stream (the frame the clouds are in), in CDR."""

from __future__ import annotations

import struct
from functools import lru_cache
from typing import Any

import numpy as np
from sofia_schemas import rosmsg

from .intrinsics import Intrinsics

CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
DISTORTION_MODELS = {"none": "plumb_bob", "brown_conrady": "plumb_bob", "inverse_brown_conrady": "plumb_bob"}


@lru_cache(maxsize=8)
def _serialized(intr: Intrinsics, frame_id: str) -> bytes:
    """CDR of the message stamped 0 (the stamp is patched per frame: it is the first header field)."""
    ts = rosmsg.typestore()
    T = ts.types
    fx, fy, cx, cy = intr.fx, intr.fy, intr.ppx, intr.ppy
    msg = T[CAMERA_INFO](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=frame_id),
        height=intr.height, width=intr.width,
        distortion_model=DISTORTION_MODELS.get(intr.model, intr.model),
        d=np.array(intr.coeffs, dtype=np.float64),
        k=np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], dtype=np.float64),
        r=np.array([1, 0, 0, 0, 1, 0, 0, 0, 1], dtype=np.float64),
        p=np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], dtype=np.float64),
        binning_x=0, binning_y=0,
        roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )  # fmt: skip
    return bytes(ts.serialize_cdr(msg, CAMERA_INFO))


def encode_camera_info(intr: Intrinsics, stamp_ns: int, frame_id: str) -> bytes:
    """CDR CameraInfo of a stream with intrinsics ``intr`` (rectified: R = I, P = [K | 0])."""
    out = bytearray(_serialized(intr, frame_id))
    struct.pack_into("<iI", out, 4, *divmod(int(stamp_ns), 1_000_000_000))  # after the CDR header
    return bytes(out)


def decode_camera_info(payload: bytes) -> Any:
    """The rosbags CameraInfo message of CDR bytes (tests, ``sofia camera record``)."""
    return rosmsg.typestore().deserialize_cdr(bytes(payload), CAMERA_INFO)
