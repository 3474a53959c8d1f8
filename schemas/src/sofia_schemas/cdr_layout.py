"""Reading a ``sensor_msgs/msg/PointCloud2``'s CDR (XCDR1, little endian) up to its point data:
bounds-checked fields that name what is cut short, and the layout a publisher's clouds share."""

from __future__ import annotations

import struct
from typing import NamedTuple

from .cloud import PointField
from .errors import SizeMismatch, TruncatedMessage, UnsupportedEncoding


class Reader:
    """Fields of CDR bytes ``buf`` read in order from ``pos`` (aligned as XCDR1 aligns them after
    the 4-byte encapsulation header); each read names its field when the bytes end first."""

    __slots__ = ("buf", "n", "pos")

    def __init__(self, buf: memoryview, pos: int = 4) -> None:
        self.buf = buf
        self.pos = pos  # 4: just after the encapsulation header
        self.n = len(buf)

    def _align(self, k: int) -> None:
        self.pos += (-(self.pos - 4)) % k

    def need(self, k: int, what: str) -> None:
        if self.pos + k > self.n:
            raise TruncatedMessage(what, self.pos + k, self.n)

    def u32(self, what: str) -> int:
        return self._int32("<I", what)

    def i32(self, what: str) -> int:
        return self._int32("<i", what)

    def _int32(self, fmt: str, what: str) -> int:
        """A 4-byte integer of struct format ``fmt`` (``<I`` or ``<i``), aligned to 4."""
        self._align(4)
        self.need(4, what)
        (v,) = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += 4
        return int(v)

    def u8(self, what: str) -> int:
        self.need(1, what)
        v = self.buf[self.pos]
        self.pos += 1
        return int(v)

    def string(self, what: str) -> str:
        n = self.u32(what + " length")
        if n == 0:
            return ""
        self.need(n, what)
        raw = bytes(self.buf[self.pos : self.pos + n])
        self.pos += n
        if raw[-1:] != b"\x00":
            raise TruncatedMessage(what + " (missing NUL terminator)", self.pos, self.n)
        try:
            return raw[:-1].decode("utf-8")
        except UnicodeDecodeError as e:
            raise UnsupportedEncoding(f"{what} is not UTF-8: {e}") from None


class Layout(NamedTuple):
    """What a PointCloud2's CDR says between its stamp and its point data: ``head`` is those bytes
    (from byte 12, the frame id's length, to the data); a publisher's clouds all share them."""

    head: bytes
    frame_id: str
    height: int
    width: int
    fields: tuple[PointField, ...]
    is_bigendian: bool
    point_step: int
    row_step: int
    n_data: int


def parse_layout(buf: memoryview) -> Layout:
    """The :class:`Layout` of CDR bytes ``buf``; raises naming the field that is cut short or wrong."""
    r = Reader(buf)
    r.i32("header.stamp.sec")
    r.u32("header.stamp.nanosec")
    frame_id = r.string("header.frame_id")
    height = r.u32("height")
    width = r.u32("width")
    n_fields = r.u32("fields length")
    if n_fields > 1024:
        raise SizeMismatch(f"PointCloud2 declares {n_fields} fields; the buffer is corrupt")
    fields = []
    for i in range(n_fields):
        name = r.string(f"fields[{i}].name")
        offset = r.u32(f"fields[{i}].offset")
        datatype = r.u8(f"fields[{i}].datatype")
        count = r.u32(f"fields[{i}].count")
        fields.append(PointField(name, offset, datatype, count))
    is_bigendian = bool(r.u8("is_bigendian"))
    point_step = r.u32("point_step")
    row_step = r.u32("row_step")
    n_data = r.u32("data length")
    head = bytes(buf[12 : r.pos])
    return Layout(head, frame_id, height, width, tuple(fields), is_bigendian, point_step, row_step, n_data)
