"""Small ROS 2 messages on the bus and in MCAP (CDR via ``rosbags``, no ROS installation).

Flange poses travel as ``geometry_msgs/msg/TransformStamped`` (parent = base, child = flange) and
blob observations as ``geometry_msgs/msg/PointStamped``; both may also be sent as pydantic JSON.
:func:`decode_flange_pose` and :func:`decode_blob` accept either and tell them apart by the first
byte (CDR encapsulation header vs ``{``).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any, TypeVar

import numpy as np
from pydantic import BaseModel

from .errors import PayloadError
from .messages import BlobObservation, FlangePose

M = TypeVar("M", bound=BaseModel)

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
POINT_STAMPED = "geometry_msgs/msg/PointStamped"


@lru_cache(maxsize=1)
def typestore() -> Any:
    """The ROS 2 Humble type store of ``rosbags``."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def msgdef(typename: str) -> str:
    """ROS 2 ``.msg`` definition text of ``typename`` with its dependencies (MCAP ``ros2msg`` schema)."""
    text, _ = typestore().generate_msgdef(typename, ros_version=2)
    return str(text)


def _header(stamp_ns: int, frame_id: str) -> Any:
    ts = typestore()
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    Time = ts.types["builtin_interfaces/msg/Time"]
    Header = ts.types["std_msgs/msg/Header"]
    return Header(stamp=Time(sec=sec, nanosec=nsec), frame_id=frame_id)


def encode_flange_pose(pose: FlangePose) -> bytes:
    """CDR ``geometry_msgs/msg/TransformStamped`` of a base -> flange pose."""
    ts = typestore()
    T = ts.types
    msg = T[TRANSFORM_STAMPED](
        header=_header(pose.stamp_ns, pose.frame_id),
        child_frame_id=pose.child_frame_id,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](*map(float, pose.translation)),
            rotation=T["geometry_msgs/msg/Quaternion"](*map(float, pose.rotation_xyzw)),
        ),
    )
    return bytes(ts.serialize_cdr(msg, TRANSFORM_STAMPED))


def encode_blob(obs: BlobObservation) -> bytes:
    """CDR ``geometry_msgs/msg/PointStamped`` of a camera-frame blob position."""
    ts = typestore()
    msg = ts.types[POINT_STAMPED](
        header=_header(obs.stamp_ns, obs.frame_id),
        point=ts.types["geometry_msgs/msg/Point"](*map(float, obs.position)),
    )
    return bytes(ts.serialize_cdr(msg, POINT_STAMPED))


def _decode(
    payload: bytes | bytearray | memoryview,
    what: str,
    model: type[M],
    typename: str,
    from_msg: Callable[[Any], M],
) -> M:
    """``model`` from pydantic JSON bytes, else ``from_msg(msg)`` of the CDR ``typename`` message;
    PayloadError naming ``what`` if neither."""
    payload = bytes(payload)
    if payload[:1] in (b"{", b" ", b"\n"):
        try:
            return model.model_validate_json(payload)
        except ValueError as e:
            raise PayloadError(f"{what} JSON is invalid: {e}") from None
    try:
        return from_msg(typestore().deserialize_cdr(payload, typename))
    except Exception as e:  # rosbags raises assorted errors on corrupt CDR
        raise PayloadError(
            f"{what} payload ({len(payload)} bytes) is neither JSON nor CDR {typename}: {e}"
        ) from None


def _stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def _flange_pose(msg: Any) -> FlangePose:
    tr, rot = msg.transform.translation, msg.transform.rotation
    return FlangePose(
        stamp_ns=_stamp_ns(msg),
        frame_id=msg.header.frame_id,
        child_frame_id=msg.child_frame_id,
        translation=(tr.x, tr.y, tr.z),
        rotation_xyzw=(rot.x, rot.y, rot.z, rot.w),
    )


def _blob(msg: Any) -> BlobObservation:
    p = msg.point
    return BlobObservation(
        stamp_ns=_stamp_ns(msg),
        frame_id=msg.header.frame_id,
        position=(float(p.x), float(p.y), float(p.z)),
        confidence=1.0,
    )


def decode_flange_pose(payload: bytes | bytearray | memoryview) -> FlangePose:
    """A :class:`FlangePose` from CDR TransformStamped or JSON bytes; PayloadError if neither."""
    return _decode(payload, "flange pose", FlangePose, TRANSFORM_STAMPED, _flange_pose)


def decode_blob(payload: bytes | bytearray | memoryview) -> BlobObservation:
    """A :class:`BlobObservation` from CDR PointStamped or JSON bytes; PayloadError if neither."""
    return _decode(payload, "blob", BlobObservation, POINT_STAMPED, _blob)


JOINT_STATE = "sensor_msgs/msg/JointState"


def encode_joint_state(
    stamp_ns: int, names: list[str], position: np.ndarray, velocity: np.ndarray | None = None,
    effort: np.ndarray | None = None, frame_id: str = "",
) -> bytes:  # fmt: skip
    """CDR ``sensor_msgs/msg/JointState``: joint ``names``, positions (rad), velocities (rad/s) and
    efforts (Nm), each (n,) or empty."""
    ts = typestore()

    def arr(v: np.ndarray | None) -> np.ndarray:
        return np.zeros(0) if v is None else np.ascontiguousarray(v, dtype=np.float64).ravel()

    msg = ts.types[JOINT_STATE](
        header=_header(stamp_ns, frame_id), name=list(names), position=arr(position),
        velocity=arr(velocity), effort=arr(effort),
    )  # fmt: skip
    return bytes(ts.serialize_cdr(msg, JOINT_STATE))


def decode_joint_state(
    payload: bytes | bytearray | memoryview,
) -> tuple[int, list[str], np.ndarray, np.ndarray, np.ndarray]:
    """(stamp_ns, names, position, velocity, effort) of CDR ``sensor_msgs/msg/JointState`` bytes;
    PayloadError when they are not one."""
    try:
        msg = typestore().deserialize_cdr(bytes(payload), JOINT_STATE)
    except Exception as e:  # rosbags raises assorted errors on corrupt CDR
        raise PayloadError(
            f"joint state payload ({len(payload)} bytes) is not CDR {JOINT_STATE}: {e}"
        ) from None
    return (
        _stamp_ns(msg),
        list(msg.name),
        np.asarray(msg.position),
        np.asarray(msg.velocity),
        np.asarray(msg.effort),
    )
