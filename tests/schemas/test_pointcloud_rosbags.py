"""The PointCloud2 codec against messages serialized independently by rosbags."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sofia_schemas import pointcloud
from sofia_schemas.pointcloud import FLOAT32, FLOAT64, UINT8, UINT16

XYZ32 = [("x", 0, FLOAT32, 1), ("y", 4, FLOAT32, 1), ("z", 8, FLOAT32, 1)]


DTYPES = {1: "i1", 2: "u1", 3: "<i2", 4: "<u2", 5: "<i4", 6: "<u4", 7: "<f4", 8: "<f8"}


def struct_dtype(fields: list[Any], point_step: int) -> np.dtype:
    """numpy structured dtype of one point (``point_step`` bytes, padding included)."""
    return np.dtype(
        {
            "names": [f[0] for f in fields],
            "formats": [(DTYPES[f[2]], (f[3],)) if f[3] > 1 else DTYPES[f[2]] for f in fields],
            "offsets": [f[1] for f in fields],
            "itemsize": point_step,
        }
    )


def _points(shape: tuple[int, ...], dtype: str, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.0, 2.0, (*shape, 3)).astype(dtype)


def _buffer(fields: list[Any], point_step: int, values: dict[str, np.ndarray], n: int) -> np.ndarray:
    """Raw uint8 buffer of ``n`` points, ``point_step`` bytes each, padding bytes 0xAB."""
    dt = struct_dtype(fields, point_step)
    raw = np.full(n * point_step, 0xAB, np.uint8)
    arr = raw.view(dt)
    for name, v in values.items():
        arr[name] = v.reshape(arr[name].shape)
    return raw


def _pack_rgb(rgb: np.ndarray) -> np.ndarray:
    """(…, 3) uint8 r g b -> (…) float32 with bits 0x00RRGGBB (the ROS packed ``rgb`` float)."""
    rgb = rgb.astype(np.uint32)
    return ((rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]).view(np.float32)


@pytest.mark.parametrize("height,width", [(4, 5), (1, 7)])
def test_xyz_float32_organized_and_unorganized(
    ros_cloud: Callable[..., bytes], height: int, width: int
) -> None:
    p = _points((height, width), "<f4")
    p[0, 0] = np.nan
    raw = _buffer(XYZ32, 12, {n: p[..., i] for i, n in enumerate("xyz")}, height * width)
    cdr = ros_cloud(XYZ32, 12, raw, height=height, width=width, frame_id="camera_depth_optical_frame")

    cloud = pointcloud.decode(cdr)

    assert cloud.frame_id == "camera_depth_optical_frame"
    assert cloud.stamp_ns == 1_700_000_000_123_456_789
    assert (cloud.height, cloud.width, cloud.point_step) == (height, width, 12)
    assert cloud.is_organized == (height > 1)
    expected = p if height > 1 else p.reshape(width, 3)
    np.testing.assert_array_equal(cloud.xyz(), expected)
    assert cloud.xyz().shape == expected.shape
    assert cloud.rgb() is None
    assert bytes(pointcloud.encode(cloud)) == cdr


def test_realsense_layout_with_padding_and_rgb(ros_cloud: Callable[..., bytes]) -> None:
    """x y z, 4 pad bytes, packed rgb at 16, point_step 32 (as the RealSense driver pads)."""
    fields = [*XYZ32, ("rgb", 16, FLOAT32, 1)]
    h, w = 6, 8
    p = _points((h, w), "<f4", seed=1)
    rgb = np.random.default_rng(2).integers(0, 256, (h, w, 3), dtype=np.uint8)
    values = {"x": p[..., 0], "y": p[..., 1], "z": p[..., 2], "rgb": _pack_rgb(rgb)}
    cdr = ros_cloud(fields, 32, _buffer(fields, 32, values, h * w), height=h, width=w)

    cloud = pointcloud.decode(cdr)

    assert cloud.point_step == 32
    np.testing.assert_array_equal(cloud.xyz(), p)
    out = cloud.rgb()
    assert out is not None
    np.testing.assert_array_equal(out, rgb)
    assert bytes(pointcloud.encode(cloud)) == cdr


def test_rgba_field_is_read_as_colour(ros_cloud: Callable[..., bytes]) -> None:
    fields = [*XYZ32, ("rgba", 12, FLOAT32, 1)]
    p = _points((5,), "<f4")
    rgb = np.random.default_rng(3).integers(0, 256, (5, 3), dtype=np.uint8)
    values = {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "rgba": _pack_rgb(rgb)}
    cloud = pointcloud.decode(ros_cloud(fields, 16, _buffer(fields, 16, values, 5), height=1, width=5))
    out = cloud.rgb()
    assert out is not None
    np.testing.assert_array_equal(out, rgb)


def test_xyz_float64(ros_cloud: Callable[..., bytes]) -> None:
    fields = [("x", 0, FLOAT64, 1), ("y", 8, FLOAT64, 1), ("z", 16, FLOAT64, 1)]
    p = _points((3, 4), "<f8")
    cdr = ros_cloud(
        fields, 24, _buffer(fields, 24, {n: p[..., i] for i, n in enumerate("xyz")}, 12), height=3, width=4
    )
    xyz = pointcloud.decode(cdr).xyz()
    assert xyz.dtype == np.float64
    np.testing.assert_array_equal(xyz, p)


def test_non_adjacent_xyz_is_gathered(ros_cloud: Callable[..., bytes]) -> None:
    """z before y with a field between them: read correctly (as a float64 copy)."""
    fields = [("x", 0, FLOAT32, 1), ("intensity", 4, UINT16, 1), ("z", 8, FLOAT32, 1), ("y", 12, FLOAT32, 1)]
    p = _points((10,), "<f4")
    intensity = np.arange(10, dtype=np.uint16) * 1000
    values = {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "intensity": intensity}
    cloud = pointcloud.decode(ros_cloud(fields, 16, _buffer(fields, 16, values, 10), height=1, width=10))
    np.testing.assert_array_equal(cloud.xyz(), p.astype(np.float64))
    np.testing.assert_array_equal(cloud.field("intensity"), intensity)


def test_row_padding(ros_cloud: Callable[..., bytes]) -> None:
    """row_step larger than point_step x width (padded rows)."""
    h, w, step, row_step = 3, 4, 16, 16 * 4 + 8
    fields = [*XYZ32, ("rgb", 12, FLOAT32, 1)]
    p = _points((h, w), "<f4")
    raw = np.full(row_step * h, 0xCD, np.uint8)
    for r in range(h):
        row = _buffer(
            fields, step, {n: p[r, :, i] for i, n in enumerate("xyz")} | {"rgb": np.zeros(w, "<f4")}, w
        )
        raw[r * row_step : r * row_step + w * step] = row
    cdr = ros_cloud(fields, step, raw, height=h, width=w, row_step=row_step)
    cloud = pointcloud.decode(cdr)
    np.testing.assert_array_equal(cloud.xyz(), p)
    assert bytes(pointcloud.encode(cloud)) == cdr


def test_encode_points_is_read_by_rosbags(ros_deserialize: Callable[..., Any]) -> None:
    p = _points((4, 5), "<f4")
    rgb = np.random.default_rng(4).integers(0, 256, (4, 5, 3), dtype=np.uint8)
    cdr = pointcloud.encode_points(p, stamp_ns=12_000_000_007, frame_id="panda_link0", rgb=rgb)

    msg = ros_deserialize(cdr)

    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (12, 7, "panda_link0")
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (4, 5, 16, 80)
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 12, 7, 1),
    ]  # fmt: skip
    assert msg.is_dense and not msg.is_bigendian
    arr = np.asarray(msg.data).view(
        struct_dtype([(f.name, f.offset, f.datatype, f.count) for f in msg.fields], 16)
    )
    np.testing.assert_array_equal(arr["x"].reshape(4, 5), p[..., 0])
    np.testing.assert_array_equal(arr["z"].reshape(4, 5), p[..., 2])
    packed = arr["rgb"].reshape(4, 5).view(np.uint32)
    np.testing.assert_array_equal(packed & 0x00FFFFFF, _pack_rgb(rgb).view(np.uint32))  # alpha byte is 255


def test_encode_points_nan_clears_is_dense(ros_deserialize: Callable[..., Any]) -> None:
    p = _points((7,), "<f8")
    p[3] = np.nan
    msg = ros_deserialize(pointcloud.encode_points(p, stamp_ns=0, frame_id="f"))
    assert not msg.is_dense
    assert pointcloud.decode(pointcloud.encode_points(p, stamp_ns=0, frame_id="f")).xyz().dtype == np.float32


# --- zero copy -------------------------------------------------------------------------------------
@pytest.mark.parametrize("wrap", [bytes, bytearray])
def test_decode_views_share_the_input_buffer(ros_cloud: Callable[..., bytes], wrap: type) -> None:
    fields = [*XYZ32, ("rgb", 16, FLOAT32, 1)]
    payload = wrap(ros_cloud(fields, 32, np.zeros(32 * 12, np.uint8), height=3, width=4))
    cloud = pointcloud.decode(payload)
    whole = np.frombuffer(payload, np.uint8)
    assert np.shares_memory(cloud.xyz(), whole)
    rgb = cloud.rgb()
    assert rgb is not None and np.shares_memory(rgb, whole)
    assert np.shares_memory(cloud.field("z"), whole)


def test_decoded_view_of_bytes_is_read_only() -> None:
    cloud = pointcloud.decode(bytes(pointcloud.encode_points(np.zeros((3, 3)), stamp_ns=0, frame_id="f")))
    with pytest.raises(ValueError):
        cloud.xyz()[0, 0] = 1.0


# --- generated layouts -----------------------------------------------------------------------------
EXTRA_TYPES = st.sampled_from([1, 2, 3, 4, 5, 6, 7, 8])


@st.composite
def layouts(draw: st.DrawFn) -> tuple[list[Any], int]:
    """Fields x y z (float32 or float64, in any order, maybe apart) plus extra fields and padding."""
    xyz_type = draw(st.sampled_from([FLOAT32, FLOAT64]))
    names = ["x", "y", "z"] + [f"f{i}" for i in range(draw(st.integers(0, 3)))]
    order = draw(st.permutations(names))
    types = {n: xyz_type if n in "xyz" else draw(EXTRA_TYPES) for n in names}
    counts = {n: 1 if n in "xyz" else draw(st.integers(1, 3)) for n in names}
    offset, fields = 0, []
    for n in order:
        size = np.dtype(DTYPES[types[n]]).itemsize
        offset += draw(st.integers(0, 5))  # padding, possibly misaligned
        fields.append((n, offset, types[n], counts[n]))
        offset += size * counts[n]
    point_step = offset + draw(st.integers(0, 9))
    return draw(st.permutations(fields)), point_step


@settings(max_examples=60, deadline=None)
@given(
    layout=layouts(),
    height=st.integers(0, 4),
    width=st.integers(0, 5),
    frame_id=st.text(st.characters(blacklist_categories=["Cs"], blacklist_characters="\x00"), max_size=12),
    stamp_ns=st.integers(0, 2**31 * 10**9 - 1),
    seed=st.integers(0, 2**32 - 1),
)
def test_generated_layouts_round_trip(
    ros_cloud: Callable[..., bytes], layout: tuple[list[Any], int], height: int, width: int,
    frame_id: str, stamp_ns: int, seed: int,
) -> None:  # fmt: skip
    fields, point_step = layout
    n = height * width
    raw = np.random.default_rng(seed).integers(0, 256, n * point_step, dtype=np.uint8)
    cdr = ros_cloud(fields, point_step, raw, height=height, width=width, frame_id=frame_id, stamp_ns=stamp_ns)
    expected = raw.view(struct_dtype(fields, point_step))

    cloud = pointcloud.decode(cdr)

    assert (cloud.frame_id, cloud.stamp_ns, cloud.n_points) == (frame_id, stamp_ns, n)
    assert sorted(cloud.field_names()) == sorted(f[0] for f in fields)
    for name, *_ in fields:
        assert cloud.field(name).tobytes() == np.ascontiguousarray(expected[name]).tobytes()
    with np.errstate(invalid="ignore"):  # random bytes hold signalling NaNs: widening quiets them
        xyz = cloud.xyz().reshape(n, 3)
        want = np.stack([expected[c].astype(np.float64) for c in "xyz"], axis=-1)
    np.testing.assert_array_equal(xyz.astype(np.float64), want)
    assert bytes(pointcloud.encode(cloud)) == cdr


@settings(max_examples=40, deadline=None)
@given(
    shape=st.sampled_from([(0,), (1,), (17,), (1, 1), (3, 5), (8, 2)]),
    with_rgb=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_encode_points_matches_rosbags(
    ros_cloud: Callable[..., bytes], shape: tuple[int, ...], with_rgb: bool, seed: int
) -> None:
    """encode_points gives the same bytes as rosbags serializing the same message field by field."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(*shape, 3)).astype(np.float32)
    rgb = rng.integers(0, 256, (*shape, 3), dtype=np.uint8) if with_rgb else None
    height, width = (shape[0], shape[1]) if len(shape) == 2 else (1, shape[0])
    fields = XYZ32 + ([("rgb", 12, FLOAT32, 1)] if with_rgb else [])
    step = 16 if with_rgb else 12
    values = {n: p[..., i] for i, n in enumerate("xyz")}
    if rgb is not None:
        # encode_points writes alpha 255 into the packed float's high byte
        values["rgb"] = (_pack_rgb(rgb).view(np.uint32) | np.uint32(0xFF000000)).view(np.float32)
    want = ros_cloud(fields, step, _buffer(fields, step, values, height * width), height=height, width=width,
                     stamp_ns=5, frame_id="panda_link0")  # fmt: skip
    assert bytes(pointcloud.encode_points(p, stamp_ns=5, frame_id="panda_link0", rgb=rgb)) == want


def test_uint8_field_with_count(ros_cloud: Callable[..., bytes]) -> None:
    fields = [*XYZ32, ("label", 12, UINT8, 4)]
    labels = np.arange(24, dtype=np.uint8).reshape(6, 4)
    values = {"x": np.ones(6, "<f4"), "y": np.zeros(6, "<f4"), "z": np.full(6, 2, "<f4"), "label": labels}
    cloud = pointcloud.decode(ros_cloud(fields, 16, _buffer(fields, 16, values, 6), height=1, width=6))
    np.testing.assert_array_equal(cloud.field("label"), labels)
    assert cloud.field("label").shape == (6, 4)
