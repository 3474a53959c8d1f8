"""Every malformed PointCloud2 raises a PointCloudError that says what is wrong."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sofia_schemas import pointcloud
from sofia_schemas.errors import (
    MissingField,
    PointCloudError,
    SizeMismatch,
    TruncatedMessage,
    UnsupportedEncoding,
)
from sofia_schemas.pointcloud import FLOAT32, FLOAT64

XYZ32 = [("x", 0, FLOAT32, 1), ("y", 4, FLOAT32, 1), ("z", 8, FLOAT32, 1)]
XYZRGB32 = [*XYZ32, ("rgb", 12, FLOAT32, 1)]


def _small() -> bytes:
    p = np.arange(18, dtype=np.float32).reshape(2, 3, 3)
    rgb = np.arange(18, dtype=np.uint8).reshape(2, 3, 3)
    return bytes(pointcloud.encode_points(p, stamp_ns=1_000_000_001, frame_id="panda_link0", rgb=rgb))


def _decode_checked(payload: bytes | bytearray) -> None:
    """Decode and touch every view: any failure must be a PointCloudError."""
    cloud = pointcloud.decode(payload)
    cloud.xyz()
    cloud.rgb()
    for name in cloud.field_names():
        cloud.field(name)


def test_big_endian_encapsulation(ros_cloud: Callable[..., bytes]) -> None:
    cdr = ros_cloud(XYZ32, 12, np.zeros(24, np.uint8), height=1, width=2, little_endian=False)
    assert cdr[:2] == b"\x00\x00"
    with pytest.raises(UnsupportedEncoding, match="big-endian"):
        pointcloud.decode(cdr)


def test_big_endian_point_data(ros_cloud: Callable[..., bytes]) -> None:
    cdr = ros_cloud(XYZ32, 12, np.zeros(24, np.uint8), height=1, width=2, is_bigendian=True)
    with pytest.raises(UnsupportedEncoding, match="is_bigendian=True"):
        pointcloud.decode(cdr)


@pytest.mark.parametrize("missing", ["x", "y", "z"])
def test_missing_coordinate(ros_cloud: Callable[..., bytes], missing: str) -> None:
    fields = [f for f in XYZRGB32 if f[0] != missing]
    with pytest.raises(MissingField, match=rf"no field '{missing}'") as e:
        pointcloud.decode(ros_cloud(fields, 16, np.zeros(32, np.uint8), height=1, width=2))
    assert "rgb" in str(e.value)  # lists what the cloud has


def test_missing_field_by_name() -> None:
    cloud = pointcloud.decode(_small())
    with pytest.raises(MissingField, match="'intensity'"):
        cloud.field("intensity")


@pytest.mark.parametrize("n_bytes", [0, 16 * 6 - 1, 16 * 6 + 1, 16 * 7])
def test_data_size_not_point_step_x_width_x_height(ros_cloud: Callable[..., bytes], n_bytes: int) -> None:
    cdr = ros_cloud(XYZRGB32, 16, np.zeros(n_bytes, np.uint8), height=2, width=3)
    with pytest.raises(
        SizeMismatch, match=rf"data has {n_bytes} bytes, expected row_step 48 x height 2 = 96"
    ):
        pointcloud.decode(cdr)


def test_row_step_smaller_than_a_row(ros_cloud: Callable[..., bytes]) -> None:
    cdr = ros_cloud(XYZRGB32, 16, np.zeros(40 * 2, np.uint8), height=2, width=3, row_step=40)
    with pytest.raises(SizeMismatch, match="row_step 40 < point_step 16 x width 3"):
        pointcloud.decode(cdr)


def test_field_beyond_point_step(ros_cloud: Callable[..., bytes]) -> None:
    cdr = ros_cloud(XYZRGB32, 14, np.zeros(28, np.uint8), height=1, width=2)
    with pytest.raises(SizeMismatch, match="'rgb' ends at byte 16, beyond point_step 14"):
        pointcloud.decode(cdr)


def test_unknown_datatype(ros_cloud: Callable[..., bytes]) -> None:
    cdr = ros_cloud([*XYZ32, ("weird", 12, 42, 1)], 16, np.zeros(16, np.uint8), height=1, width=1)
    with pytest.raises(UnsupportedEncoding, match="'weird' has unknown datatype 42"):
        pointcloud.decode(cdr)


def test_not_cdr_at_all() -> None:
    with pytest.raises(UnsupportedEncoding, match="encapsulation header is 7b226122"):
        pointcloud.decode(b'{"a": 1}')


def test_every_truncation_raises_truncated() -> None:
    full = _small()
    _decode_checked(full)
    for n in range(len(full)):
        with pytest.raises(
            TruncatedMessage, match=r"CDR buffer truncated while reading .*: need \d+ bytes, have"
        ):
            pointcloud.decode(full[:n])


def test_truncation_names_the_field() -> None:
    full = _small()
    with pytest.raises(TruncatedMessage, match=r"reading data \(96 bytes\)"):
        pointcloud.decode(full[:-20])


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_garbage_bytes(garbage: bytes) -> None:
    for payload in (garbage, pointcloud.CDR_LE + garbage):
        try:
            _decode_checked(payload)
        except PointCloudError:
            pass


@settings(max_examples=300, deadline=None)
@given(position=st.integers(4, 200), value=st.integers(0, 255), cut=st.integers(0, 400))
def test_corrupted_valid_message(position: int, value: int, cut: int) -> None:
    """A byte changed (and maybe the tail cut) in a valid message: a valid cloud or a PointCloudError."""
    buf = bytearray(_small())
    buf[position % len(buf)] = value
    try:
        _decode_checked(bytes(buf[: max(cut, 4)]))
    except PointCloudError:
        pass


def test_encode_points_rejects_bad_shapes() -> None:
    with pytest.raises(ValueError, match=r"shape \(N, 3\) or \(H, W, 3\), got \(4, 2\)"):
        pointcloud.encode_points(np.zeros((4, 2)), stamp_ns=0, frame_id="f")
    with pytest.raises(ValueError, match="rgb must be uint8 of shape"):
        pointcloud.encode_points(np.zeros((4, 3)), stamp_ns=0, frame_id="f", rgb=np.zeros((4, 3)))


def test_errors_are_value_errors() -> None:
    """Callers that catch ValueError (the CLI, services) also catch codec errors."""
    with pytest.raises(ValueError):
        pointcloud.decode(b"\x00\x01")


def test_x_y_z_at_the_same_offset(ros_cloud: Callable[..., bytes]) -> None:
    fields = [("x", 0, FLOAT32, 1), ("y", 0, FLOAT32, 1), ("z", 0, FLOAT32, 1)]
    with pytest.raises(SizeMismatch, match=r"PointFields 'x' .* and 'y' .* overlap"):
        pointcloud.decode(ros_cloud(fields, 12, np.zeros(24, np.uint8), height=1, width=2))


def test_float64_x_overlapping_y(ros_cloud: Callable[..., bytes]) -> None:
    fields = [("x", 0, FLOAT64, 1), ("y", 4, FLOAT32, 1), ("z", 8, FLOAT32, 1)]
    with pytest.raises(SizeMismatch, match=r"'x' \(bytes up to 8\) and 'y' \(from byte 4\) overlap"):
        pointcloud.decode(ros_cloud(fields, 12, np.zeros(24, np.uint8), height=1, width=2))


def test_zero_count(ros_cloud: Callable[..., bytes]) -> None:
    fields = [*XYZ32, ("rgb", 12, FLOAT32, 0)]
    with pytest.raises(SizeMismatch, match="'rgb' has count 0; it must be at least 1"):
        pointcloud.decode(ros_cloud(fields, 16, np.zeros(32, np.uint8), height=1, width=2))


def test_a_field_named_twice(ros_cloud: Callable[..., bytes]) -> None:
    fields = [*XYZ32, ("x", 12, FLOAT32, 1)]
    with pytest.raises(SizeMismatch, match=r"names a field twice: \['x'\]"):
        pointcloud.decode(ros_cloud(fields, 16, np.zeros(32, np.uint8), height=1, width=2))


@pytest.mark.parametrize("extra", [4, 1_000_000])
def test_bytes_after_the_message(extra: int) -> None:
    with pytest.raises(SizeMismatch, match=rf"has {extra} bytes after its last field"):
        pointcloud.decode(_small() + b"\xab" * extra)


def test_alignment_padding_is_accepted(ros_cloud: Callable[..., bytes]) -> None:
    """Up to 3 bytes may pad a serialized message to a multiple of 4 (DDS does)."""
    for pad in range(4):
        cloud = pointcloud.decode(_small() + b"\x00" * pad)
        assert cloud.n_points == 6
    assert pointcloud.decode(ros_cloud(XYZRGB32, 16, np.zeros(96, np.uint8), height=2, width=3)).n_points == 6


def test_clouds_of_other_layouts_are_parsed_afresh() -> None:
    """decode() reuses the last cloud's parse only when the bytes between its stamp and its data are
    the same: another frame id of the same length, other fields, another shape are read as sent."""
    a = _small()
    b = bytes(pointcloud.encode_points(np.ones((2, 3, 3), np.float32), stamp_ns=5, frame_id="panda_link1"))
    c = bytes(
        pointcloud.encode_points(np.full((3, 2, 3), 2.0, np.float32), stamp_ns=7, frame_id="panda_link1")
    )
    expected = {
        a: (1_000_000_001, "panda_link0", (2, 3), ["x", "y", "z", "rgb"], 0.0),
        b: (5, "panda_link1", (2, 3), ["x", "y", "z"], 1.0),
        c: (7, "panda_link1", (3, 2), ["x", "y", "z"], 2.0),
    }
    for payload in (a, b, c, c, a, b, a):
        cloud = pointcloud.decode(payload)
        stamp, frame, shape, names, first = expected[payload]
        assert (cloud.stamp_ns, cloud.frame_id, cloud.shape, cloud.field_names()) == (
            stamp,
            frame,
            shape,
            names,
        )
        assert cloud.xyz()[0, 0, 0] == first
    with pytest.raises(TruncatedMessage, match="is_dense"):  # the same layout, the last byte cut
        pointcloud.decode(_without_is_dense(a))


def _without_is_dense(payload: bytes) -> bytes:
    """``payload`` cut just before its is_dense byte (after the point data)."""
    cloud = pointcloud.decode(payload)
    end = bytes(payload).index(bytes(cloud.data)) + len(cloud.data)
    return payload[:end]
