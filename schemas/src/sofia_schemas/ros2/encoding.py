"""The ROS type named in a Zenoh encoding (``application/cdr;<pkg>/msg/<Name>``), checked.

A payload is decoded as the type its encoding names: a ``geometry_msgs/msg/PoseStamped`` on the
flange key is converted (its pose is the flange's, in ``header.frame_id``), a type the key cannot
carry is refused with a :class:`~sofia_schemas.PayloadError` naming it. Payloads without a typed
encoding (JSON, plain bytes) are told apart by their first byte as before.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..errors import PayloadError
from ..frames import FLANGE_FRAME
from ..messages import FlangePose
from ..rosmsg import TRANSFORM_STAMPED, decode_flange_pose
from .convert import POINTCLOUD2, POSE_STAMPED, stamp_ns
from .typesupport import decode

CDR_PREFIX = "application/cdr;"


def encoding_type(encoding: object) -> str:
    """``application/cdr;sensor_msgs/msg/PointCloud2`` -> ``sensor_msgs/msg/PointCloud2``; "" if none."""
    text = str(encoding) if encoding is not None else ""
    return text[len(CDR_PREFIX) :].strip() if text.startswith(CDR_PREFIX) else ""


def decode_flange(payload: bytes, encoding: object = None, flange_frame: str = FLANGE_FRAME) -> FlangePose:
    """A base -> flange pose from CDR TransformStamped, CDR PoseStamped (child ``flange_frame``) or JSON."""
    typename = encoding_type(encoding)
    if typename in ("", TRANSFORM_STAMPED):
        return decode_flange_pose(payload)
    if typename == POSE_STAMPED:
        try:
            msg = decode(payload, POSE_STAMPED)
        except ValueError as e:
            raise PayloadError(f"flange pose: {e}") from None
        p, q = msg.pose.position, msg.pose.orientation
        return FlangePose(stamp_ns=stamp_ns(msg.header.stamp), frame_id=msg.header.frame_id,
                          child_frame_id=flange_frame, translation=(p.x, p.y, p.z),
                          rotation_xyzw=(q.x, q.y, q.z, q.w))  # fmt: skip
    raise PayloadError(
        f"flange pose encoded as {typename!r}: expected {TRANSFORM_STAMPED}, {POSE_STAMPED} or JSON FlangePose"
    )


def check_cloud_encoding(encoding: object, key: str) -> None:
    """PayloadError when ``encoding`` names a CDR type other than PointCloud2."""
    typename = encoding_type(encoding)
    if typename and typename != POINTCLOUD2:
        raise PayloadError(f"{key}: payload encoded as {typename!r}, expected {POINTCLOUD2}")


def typed_cloud(sample: Any, on_error: Callable[[str], None]) -> bool:
    """False, after ``on_error(message)``, when a sample's encoding names another type than PointCloud2."""
    try:
        check_cloud_encoding(sample.encoding, str(sample.key_expr))
    except PayloadError as e:
        on_error(str(e))
        return False
    return True
