"""Header stamps of recorded CDR messages, rewritten without decoding the message.

Every message type SofIA records starts with a ``std_msgs/msg/Header``, whose stamp sits right
after the 4-byte CDR encapsulation header: ``int32 sec, uint32 nanosec``, little endian.
"""

from __future__ import annotations

import struct

from .errors import RecordingError

HEADER_FIRST = frozenset(
    {
        "sensor_msgs/msg/PointCloud2",
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CameraInfo",
        "geometry_msgs/msg/TransformStamped",
        "geometry_msgs/msg/PointStamped",
        "geometry_msgs/msg/PoseStamped",
    }
)
_CDR_LE = b"\x00\x01"
_STAMP = struct.Struct("<iI")


def restamp(cdr: bytes, stamp_ns: int) -> bytes:
    """``cdr`` with its header stamp replaced by ``stamp_ns`` (one copy of the message).

    cdr: little-endian CDR bytes of a message that starts with ``std_msgs/msg/Header``.
    """
    if len(cdr) < 4 + _STAMP.size or cdr[:2] != _CDR_LE:
        raise RecordingError(
            f"cannot restamp a {len(cdr)}-byte message with encapsulation {cdr[:4].hex()} (need little-endian CDR)"
        )
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return b"".join((cdr[:4], _STAMP.pack(sec, nsec), memoryview(cdr)[4 + _STAMP.size :]))


def stamp_ns(cdr: bytes) -> int:
    """The header stamp of ``cdr`` (see :func:`restamp`), nanoseconds."""
    sec, nsec = _STAMP.unpack_from(cdr, 4)
    return int(sec) * 1_000_000_000 + int(nsec)
