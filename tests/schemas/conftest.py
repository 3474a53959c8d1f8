"""PointCloud2 messages built field by field with ``rosbags`` (independent of the SofIA codec)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

PC2 = "sensor_msgs/msg/PointCloud2"


def build_ros_cloud(
    fields: list[tuple[str, int, int, int]], point_step: int, data: np.ndarray, *, height: int, width: int,
    row_step: int | None = None, stamp_ns: int = 1_700_000_000_123_456_789, frame_id: str = "panda_link0",
    is_dense: bool = True, is_bigendian: bool = False, little_endian: bool = True,
) -> bytes:  # fmt: skip
    """CDR bytes of a PointCloud2 serialized by rosbags; ``data`` is the raw uint8 point buffer."""
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    sec, nsec = divmod(stamp_ns, 1_000_000_000)
    msg = T[PC2](
        header=T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame_id
        ),
        height=height,
        width=width,
        fields=[
            T["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=c) for n, o, d, c in fields
        ],
        is_bigendian=is_bigendian,
        point_step=point_step,
        row_step=point_step * width if row_step is None else row_step,
        data=np.ascontiguousarray(data, dtype=np.uint8).ravel(),
        is_dense=is_dense,
    )
    return bytes(ts.serialize_cdr(msg, PC2, little_endian=little_endian))


def deserialize_ros_cloud(cdr: bytes | bytearray) -> Any:
    return get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(bytes(cdr), PC2)


@pytest.fixture(scope="session")
def ros_cloud() -> Callable[..., bytes]:
    return build_ros_cloud


@pytest.fixture(scope="session")
def ros_deserialize() -> Callable[[bytes | bytearray], Any]:
    return deserialize_ros_cloud
