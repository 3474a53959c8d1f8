"""ROS 2 ``sensor_msgs/msg/PointCloud2`` in CDR (XCDR1, little endian), with numpy views.

Decoding never copies the point buffer: :func:`decode` returns a :class:`PointCloud2` whose
``data`` is a ``memoryview`` into the received bytes, and :meth:`PointCloud2.xyz` is a strided
numpy view of it when x, y, z are adjacent float32 (the layout of every common driver).
Encoding copies the point buffer once, straight into the output message.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from .errors import MissingField, SizeMismatch, TruncatedMessage, UnsupportedEncoding

# sensor_msgs/msg/PointField datatypes
INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)
DATATYPE_DTYPES: dict[int, str] = {
    INT8: "i1", UINT8: "u1", INT16: "<i2", UINT16: "<u2",
    INT32: "<i4", UINT32: "<u4", FLOAT32: "<f4", FLOAT64: "<f8",
}  # fmt: skip

CDR_LE = b"\x00\x01\x00\x00"
CDR_BE = b"\x00\x00\x00\x00"
MAX_POINTS = 50_000_000


@dataclass(frozen=True)
class PointField:
    """One ``sensor_msgs/msg/PointField``."""

    name: str
    offset: int
    datatype: int
    count: int = 1

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(DATATYPE_DTYPES[self.datatype])


XYZ_FIELDS = (PointField("x", 0, FLOAT32), PointField("y", 4, FLOAT32), PointField("z", 8, FLOAT32))
XYZRGB_FIELDS = (*XYZ_FIELDS, PointField("rgb", 12, FLOAT32))


@dataclass
class PointCloud2:
    """A decoded PointCloud2. ``data`` is a buffer of ``row_step * height`` bytes (not copied)."""

    stamp_ns: int
    frame_id: str
    height: int
    width: int
    fields: tuple[PointField, ...]
    point_step: int
    row_step: int
    data: memoryview | bytes | bytearray
    is_dense: bool = False
    is_bigendian: bool = False
    _field_index: dict[str, PointField] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._field_index = {f.name: f for f in self.fields}
        self.validate()

    # --- checks -----------------------------------------------------------
    def validate(self) -> None:
        """Raise a :class:`PointCloudError` naming what is inconsistent."""
        if self.is_bigendian:
            raise UnsupportedEncoding("PointCloud2 is_bigendian=True: big-endian point data is not supported")
        if self.height < 0 or self.width < 0:
            raise SizeMismatch(f"PointCloud2 has negative size {self.height}x{self.width}")
        if self.height * self.width > MAX_POINTS:
            raise SizeMismatch(f"PointCloud2 of {self.height}x{self.width} exceeds {MAX_POINTS} points")
        for f in self.fields:
            if f.datatype not in DATATYPE_DTYPES:
                raise UnsupportedEncoding(f"PointField {f.name!r} has unknown datatype {f.datatype}")
            end = f.offset + f.dtype.itemsize * max(f.count, 1)
            if end > self.point_step:
                raise SizeMismatch(
                    f"PointField {f.name!r} ends at byte {end}, beyond point_step {self.point_step}"
                )
        if self.height * self.width and self.row_step < self.point_step * self.width:
            raise SizeMismatch(
                f"row_step {self.row_step} < point_step {self.point_step} x width {self.width}"
            )
        need = self.row_step * self.height
        if len(self.data) != need:
            raise SizeMismatch(
                f"PointCloud2 data has {len(self.data)} bytes, expected row_step {self.row_step} x "
                f"height {self.height} = {need}"
            )
        for name in ("x", "y", "z"):
            if name not in self._field_index:
                raise MissingField(name, [f.name for f in self.fields])

    # --- views ------------------------------------------------------------
    @property
    def n_points(self) -> int:
        return self.height * self.width

    @property
    def is_organized(self) -> bool:
        return self.height > 1

    @property
    def shape(self) -> tuple[int, ...]:
        """(H, W) for organized clouds, (N,) otherwise."""
        return (self.height, self.width) if self.is_organized else (self.n_points,)

    def field_names(self) -> list[str]:
        return [f.name for f in self.fields]

    def has_field(self, name: str) -> bool:
        return name in self._field_index

    def _field_view(self, f: PointField, dtype: np.dtype, offset: int = 0, count: int = 1) -> np.ndarray:
        n = self.n_points
        buf = np.frombuffer(self.data, dtype=np.uint8)
        if count == 1:
            return (
                np.ndarray(
                    shape=(self.height, self.width),
                    dtype=dtype,
                    buffer=buf,
                    offset=f.offset + offset,
                    strides=(self.row_step, self.point_step),
                ).reshape(self.shape)
                if n
                else np.zeros(self.shape, dtype)
            )
        return (
            np.ndarray(
                shape=(self.height, self.width, count),
                dtype=dtype,
                buffer=buf,
                offset=f.offset + offset,
                strides=(self.row_step, self.point_step, dtype.itemsize),
            ).reshape((*self.shape, count))
            if n
            else np.zeros((*self.shape, count), dtype)
        )

    def field(self, name: str) -> np.ndarray:
        """Read-only view of one field, shape ``shape`` (or ``shape + (count,)``)."""
        f = self._field_index.get(name)
        if f is None:
            raise MissingField(name, self.field_names())
        return self._field_view(f, f.dtype, count=f.count)

    def xyz(self) -> np.ndarray:
        """Points, shape ``shape + (3,)``, in ``frame_id``, metres.

        A zero-copy view when x, y, z are consecutive fields of one float type, else a float64 copy.
        """
        fx, fy, fz = (self._field_index[n] for n in ("x", "y", "z"))
        size = fx.dtype.itemsize
        if (
            fx.datatype == fy.datatype == fz.datatype
            and fx.datatype in (FLOAT32, FLOAT64)
            and fy.offset == fx.offset + size
            and fz.offset == fx.offset + 2 * size
        ):
            return self._field_view(fx, fx.dtype, count=3)
        return np.stack([self.field(n).astype(np.float64) for n in ("x", "y", "z")], axis=-1)

    def rgb(self) -> np.ndarray | None:
        """Colours as a (…, 3) uint8 view (r, g, b) of the packed ``rgb``/``rgba`` field, or None."""
        f = self._field_index.get("rgb") or self._field_index.get("rgba")
        if f is None or f.dtype.itemsize != 4:
            return None
        bgra = self._field_view(f, np.dtype("u1"), count=4)
        return bgra[..., 2::-1]


# --- CDR reading ------------------------------------------------------------
class _Reader:
    __slots__ = ("buf", "n", "pos")

    def __init__(self, buf: memoryview) -> None:
        self.buf = buf
        self.pos = 4  # after the encapsulation header
        self.n = len(buf)

    def _align(self, k: int) -> None:
        self.pos += (-(self.pos - 4)) % k

    def _need(self, k: int, what: str) -> None:
        if self.pos + k > self.n:
            raise TruncatedMessage(what, self.pos + k, self.n)

    def u32(self, what: str) -> int:
        self._align(4)
        self._need(4, what)
        (v,) = struct.unpack_from("<I", self.buf, self.pos)
        self.pos += 4
        return int(v)

    def i32(self, what: str) -> int:
        self._align(4)
        self._need(4, what)
        (v,) = struct.unpack_from("<i", self.buf, self.pos)
        self.pos += 4
        return int(v)

    def u8(self, what: str) -> int:
        self._need(1, what)
        v = self.buf[self.pos]
        self.pos += 1
        return int(v)

    def string(self, what: str) -> str:
        n = self.u32(what + " length")
        if n == 0:
            return ""
        self._need(n, what)
        raw = bytes(self.buf[self.pos : self.pos + n])
        self.pos += n
        if raw[-1:] != b"\x00":
            raise TruncatedMessage(what + " (missing NUL terminator)", self.pos, self.n)
        try:
            return raw[:-1].decode("utf-8")
        except UnicodeDecodeError as e:
            raise UnsupportedEncoding(f"{what} is not UTF-8: {e}") from None


def decode(payload: bytes | bytearray | memoryview) -> PointCloud2:
    """Decode CDR bytes of a ``sensor_msgs/msg/PointCloud2`` without copying the point buffer."""
    buf = memoryview(payload).cast("B")
    if len(buf) < 4:
        raise TruncatedMessage("CDR encapsulation header", 4, len(buf))
    head = bytes(buf[:4])
    if head[:2] == CDR_BE[:2]:
        raise UnsupportedEncoding(
            f"CDR payload is big-endian (encapsulation {head.hex()}); only little-endian CDR is supported"
        )
    if head[:2] != CDR_LE[:2]:
        raise UnsupportedEncoding(
            f"not a CDR PointCloud2: encapsulation header is {head.hex()}, expected 00010000"
        )
    r = _Reader(buf)
    sec = r.i32("header.stamp.sec")
    nsec = r.u32("header.stamp.nanosec")
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
    r._need(n_data, f"data ({n_data} bytes)")
    data = buf[r.pos : r.pos + n_data]
    r.pos += n_data
    is_dense = bool(r.u8("is_dense"))
    return PointCloud2(
        stamp_ns=sec * 1_000_000_000 + nsec,
        frame_id=frame_id,
        height=height,
        width=width,
        fields=tuple(fields),
        point_step=point_step,
        row_step=row_step,
        data=data,
        is_dense=is_dense,
        is_bigendian=is_bigendian,
    )


# --- CDR writing ------------------------------------------------------------
def _header_bytes(
    stamp_ns: int,
    frame_id: str,
    height: int,
    width: int,
    fields: tuple[PointField, ...],
    point_step: int,
    row_step: int,
    n_data: int,
) -> bytes:
    out = bytearray(CDR_LE)

    def align(k: int) -> None:
        out.extend(b"\x00" * ((-(len(out) - 4)) % k))

    def u32(v: int) -> None:
        align(4)
        out.extend(struct.pack("<I", v))

    def string(s: str) -> None:
        b = s.encode("utf-8") + b"\x00"
        u32(len(b))
        out.extend(b)

    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    align(4)
    out.extend(struct.pack("<iI", sec, nsec))
    string(frame_id)
    u32(height)
    u32(width)
    u32(len(fields))
    for f in fields:
        string(f.name)
        u32(f.offset)
        out.append(f.datatype)
        u32(f.count)
    out.append(0)  # is_bigendian
    u32(point_step)
    u32(row_step)
    u32(n_data)
    return bytes(out)


def encode(cloud: PointCloud2) -> bytes:
    """CDR bytes of ``cloud`` (one copy of the point buffer, straight into the output)."""
    head = _header_bytes(
        cloud.stamp_ns, cloud.frame_id, cloud.height, cloud.width, cloud.fields,
        cloud.point_step, cloud.row_step, len(cloud.data),
    )  # fmt: skip
    return b"".join((head, cloud.data, b"\x01" if cloud.is_dense else b"\x00"))


def encode_points(
    points: np.ndarray,
    *,
    stamp_ns: int,
    frame_id: str,
    rgb: np.ndarray | None = None,
) -> bytearray:
    """CDR PointCloud2 bytes from points, written straight into the output (one copy).

    points: (N, 3) or organized (H, W, 3) float, in ``frame_id``, metres; NaN marks missing points.
    rgb: optional (…, 3) uint8 colours with the same leading shape, packed as the ``rgb`` float field.
    Layout: x, y, z float32 (+ rgb float32), point_step 12 (16 with rgb).
    """
    points = np.asarray(points)
    if points.ndim not in (2, 3) or points.shape[-1] != 3:
        raise ValueError(f"points must have shape (N, 3) or (H, W, 3), got {points.shape}")
    height, width = (points.shape[0], points.shape[1]) if points.ndim == 3 else (1, points.shape[0])
    fields = XYZ_FIELDS if rgb is None else XYZRGB_FIELDS
    point_step = 12 if rgb is None else 16
    if rgb is not None:
        rgb = np.asarray(rgb)
        if rgb.shape != points.shape or rgb.dtype != np.uint8:
            raise ValueError(f"rgb must be uint8 of shape {points.shape}, got {rgb.dtype} {rgb.shape}")
    n = height * width
    n_data = n * point_step
    head = _header_bytes(stamp_ns, frame_id, height, width, fields, point_step, point_step * width, n_data)
    out = bytearray(len(head) + n_data + 1)
    out[: len(head)] = head
    body = np.frombuffer(out, dtype=np.uint8, count=n_data, offset=len(head)).reshape(n, point_step)
    xyz = body.view("<f4")[:, :3]
    flat = points.reshape(n, 3)
    for axis in range(3):  # three 1-D strided copies: ~4x faster than one (n, 3) strided copy
        xyz[:, axis] = flat[:, axis]
    if rgb is not None:
        bgra = body[:, 12:16]
        bgra[:, 0] = rgb.reshape(n, 3)[:, 2]
        bgra[:, 1] = rgb.reshape(n, 3)[:, 1]
        bgra[:, 2] = rgb.reshape(n, 3)[:, 0]
        bgra[:, 3] = 255
    out[-1] = 0 if np.isnan(points).any() else 1
    return out


def from_points(
    points: np.ndarray, *, stamp_ns: int, frame_id: str, rgb: np.ndarray | None = None
) -> PointCloud2:
    """A :class:`PointCloud2` holding ``points`` (see :func:`encode_points`)."""
    return decode(encode_points(points, stamp_ns=stamp_ns, frame_id=frame_id, rgb=rgb))


def info(cloud: PointCloud2) -> dict[str, object]:
    """Summary of a cloud (the fields of :class:`sofia_schemas.PointCloudInfo`)."""
    xyz = cloud.xyz()
    finite = int(np.isfinite(xyz).all(axis=-1).sum()) if cloud.n_points else 0
    return {
        "stamp_ns": cloud.stamp_ns,
        "frame_id": cloud.frame_id,
        "height": cloud.height,
        "width": cloud.width,
        "fields": cloud.field_names(),
        "point_step": cloud.point_step,
        "n_points": cloud.n_points,
        "n_finite": finite,
        "is_dense": cloud.is_dense,
    }
