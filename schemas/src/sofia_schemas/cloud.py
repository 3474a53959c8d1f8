"""The PointCloud2 message as numpy views: fields, layouts, and zero-copy access to x, y, z and rgb."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from .errors import MissingField, SizeMismatch, UnsupportedEncoding

# sensor_msgs/msg/PointField datatypes
INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)
DATATYPE_DTYPES: dict[int, str] = {
    INT8: "i1", UINT8: "u1", INT16: "<i2", UINT16: "<u2",
    INT32: "<i4", UINT32: "<u4", FLOAT32: "<f4", FLOAT64: "<f8",
}  # fmt: skip

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
        spans = []
        for f in self.fields:
            if f.datatype not in DATATYPE_DTYPES:
                raise UnsupportedEncoding(f"PointField {f.name!r} has unknown datatype {f.datatype}")
            if f.count < 1:
                raise SizeMismatch(f"PointField {f.name!r} has count {f.count}; it must be at least 1")
            end = f.offset + f.dtype.itemsize * f.count
            if end > self.point_step:
                raise SizeMismatch(
                    f"PointField {f.name!r} ends at byte {end}, beyond point_step {self.point_step}"
                )
            spans.append((f.offset, end, f.name))
        spans.sort()
        for (_, end_a, a), (start_b, _, b) in itertools.pairwise(spans):
            if start_b < end_a:
                raise SizeMismatch(
                    f"PointFields {a!r} (bytes up to {end_a}) and {b!r} (from byte {start_b}) overlap"
                )
        if len(self._field_index) != len(self.fields):
            names = [f.name for f in self.fields]
            raise SizeMismatch(
                f"PointCloud2 names a field twice: {sorted(n for n in set(names) if names.count(n) > 1)}"
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
