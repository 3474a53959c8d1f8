"""MCAP writer and readers: ROS 2 layout, lazy iteration, windows, metadata, ground truth, errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from sofia_replay import mcap_io
from sofia_replay.errors import (
    BadTruthError,
    NotAnMcapError,
    RecordingError,
    RecordingNotFoundError,
    UnknownSchemaError,
)
from sofia_replay.mcap_io import McapWriter
from sofia_schemas import BlobObservation, FlangePose, pointcloud, rosmsg
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE, TOPIC_POINTS

T0 = 1_700_000_000_000_000_000
PERIOD = 100_000_000


def _cloud(i: int, shape: tuple[int, ...] = (6, 8)) -> bytearray:
    rng = np.random.default_rng(i)
    p = rng.normal(size=(*shape, 3)).astype(np.float32)
    rgb = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    return pointcloud.encode_points(p, stamp_ns=T0 + i * PERIOD, frame_id="panda_link0", rgb=rgb)


def _pose(i: int) -> FlangePose:
    return FlangePose(
        stamp_ns=T0 + i * PERIOD, translation=(0.4, 0.01 * i, 0.5), rotation_xyzw=(1.0, 0.0, 0.0, 0.0)
    )


@pytest.fixture
def recording(tmp_path: Path) -> Path:
    path = tmp_path / "rec.mcap"
    with McapWriter(path) as w:
        for i in range(5):
            w.write_cloud(TOPIC_POINTS, _cloud(i), T0 + i * PERIOD)
            w.write_cloud(TOPIC_CAMERA_POINTS, _cloud(100 + i, (20,)), T0 + i * PERIOD + 1)
            w.write_flange_pose(TOPIC_FLANGE_POSE, _pose(i))
        w.write_blob(TOPIC_BLOB, BlobObservation(stamp_ns=T0 + 2 * PERIOD, position=(0.01, -0.02, 0.45)))
        w.add_metadata("lab", {"operator": "sofia", "board": "v1"})
        w.add_truth({"type": "scenes", "objects": [{"center": [0.5, 0.0, 0.03]}]})
    return path


def test_messages_in_log_time_order_with_recorded_bytes(recording: Path) -> None:
    msgs = list(mcap_io.iter_messages(recording))
    assert len(msgs) == 16
    times = [m.log_time_ns for m in msgs]
    assert times == sorted(times)
    clouds = [m for m in msgs if m.topic == TOPIC_POINTS]
    assert [m.data for m in clouds] == [bytes(_cloud(i)) for i in range(5)]
    assert {m.schema_name for m in clouds} == {rosmsg.POINTCLOUD2}
    assert clouds[0].publish_time_ns == clouds[0].log_time_ns == T0


def test_topic_and_time_window(recording: Path) -> None:
    msgs = list(
        mcap_io.iter_messages(recording, [TOPIC_POINTS], start_ns=T0 + PERIOD, end_ns=T0 + 3 * PERIOD)
    )
    assert [(m.topic, m.log_time_ns) for m in msgs] == [
        (TOPIC_POINTS, T0 + PERIOD),
        (TOPIC_POINTS, T0 + 2 * PERIOD),
    ]


def test_iter_clouds(recording: Path) -> None:
    out = list(mcap_io.iter_clouds(recording))
    assert [t for t, _, _ in out] == [TOPIC_POINTS, TOPIC_CAMERA_POINTS] * 5
    topic, t_ns, cloud = out[2]
    assert (topic, t_ns, cloud.shape, cloud.frame_id) == (TOPIC_POINTS, T0 + PERIOD, (6, 8), "panda_link0")
    np.testing.assert_array_equal(cloud.xyz(), pointcloud.decode(_cloud(1)).xyz())
    cam = list(mcap_io.iter_clouds(recording, topics=[TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE]))
    assert len(cam) == 5 and all(c.shape == (20,) for _, _, c in cam)
    assert list(mcap_io.iter_clouds(recording, topics=[TOPIC_FLANGE_POSE])) == []


def test_poses_and_blobs(recording: Path) -> None:
    poses = list(mcap_io.iter_flange_poses(recording))
    assert [p for _, p in poses] == [_pose(i) for i in range(5)]
    blobs = list(mcap_io.iter_blobs(recording))
    assert len(blobs) == 1 and blobs[0][1].position == (0.01, -0.02, 0.45)


def test_metadata_and_truth(recording: Path) -> None:
    meta = mcap_io.read_metadata(recording)
    assert meta["lab"] == {"operator": "sofia", "board": "v1"}
    assert mcap_io.read_truth(recording) == {"type": "scenes", "objects": [{"center": [0.5, 0.0, 0.03]}]}


def test_summary(recording: Path) -> None:
    s = mcap_io.summary(recording)
    assert s.n_messages == 16
    assert {t: (v.schema_name, v.count) for t, v in s.topics.items()} == {
        TOPIC_POINTS: (rosmsg.POINTCLOUD2, 5),
        TOPIC_CAMERA_POINTS: (rosmsg.POINTCLOUD2, 5),
        TOPIC_FLANGE_POSE: (rosmsg.TRANSFORM_STAMPED, 5),
        TOPIC_BLOB: (rosmsg.POINT_STAMPED, 1),
    }
    assert (s.start_ns, s.end_ns) == (T0, T0 + 4 * PERIOD + 1)
    assert s.duration_s == pytest.approx(0.4)
    assert sorted(s.metadata) == ["lab", "sofia.truth"]
    assert "/pc_glob" in s.format() and s.to_dict()["topics"][TOPIC_BLOB]["count"] == 1


def test_ros2_layout_readable_from_the_file_alone(recording: Path) -> None:
    """What Foxglove does: profile ros2, ros2msg schemas, cdr messages decoded from the schema text."""
    with open(recording, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        for ch in summary.channels.values():
            schema = summary.schemas[ch.schema_id]
            assert (ch.message_encoding, schema.encoding) == ("cdr", "ros2msg")
        decoded: dict[str, Any] = {}
        for schema, channel, message in reader.iter_messages():
            assert schema is not None
            store = get_typestore(Stores.EMPTY)
            store.register(get_types_from_msg(schema.data.decode(), schema.name))
            decoded.setdefault(channel.topic, store.deserialize_cdr(message.data, schema.name))
    assert decoded[TOPIC_POINTS].width == 8 and decoded[TOPIC_POINTS].point_step == 16
    assert decoded[TOPIC_FLANGE_POSE].child_frame_id == "panda_link8"
    assert decoded[TOPIC_BLOB].point.z == 0.45


def test_uncompressed_and_lz4(tmp_path: Path) -> None:
    for compression in ("none", "lz4"):
        path = tmp_path / f"{compression}.mcap"
        with McapWriter(path, compression=compression) as w:
            w.write_cloud(TOPIC_POINTS, _cloud(0), T0)
        assert [m.data for m in mcap_io.iter_messages(path)] == [bytes(_cloud(0))]


def test_writer_errors(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="compression 'gzip' is not one of"):
        McapWriter(tmp_path / "a.mcap", compression="gzip")
    with McapWriter(tmp_path / "b.mcap") as w:
        w.write_cloud(TOPIC_POINTS, _cloud(0), T0)
        with pytest.raises(
            RecordingError, match="topic '/pc_glob' already carries sensor_msgs/msg/PointCloud2"
        ):
            w.write_flange_pose(TOPIC_POINTS, _pose(0))
        with pytest.raises(UnknownSchemaError, match="'my_msgs/msg/Nope'"):
            w.write_raw("/x", "my_msgs/msg/Nope", b"\x00\x01\x00\x00", T0)
        with pytest.raises(RecordingError, match=r"values must be strings, got \{'n': 'int'\}"):
            w.add_metadata("m", {"n": 1})  # type: ignore[dict-item]
    with pytest.raises(RecordingError, match="is closed"):
        w.write_cloud(TOPIC_POINTS, _cloud(0), T0)


def test_reader_errors(tmp_path: Path, recording: Path) -> None:
    with pytest.raises(RecordingNotFoundError, match="does not exist"):
        list(mcap_io.iter_messages(tmp_path / "missing.mcap"))
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    with pytest.raises(NotAnMcapError, match="is not a readable MCAP file"):
        mcap_io.summary(bad)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[:3000])
    with pytest.raises(NotAnMcapError):
        list(mcap_io.iter_messages(cut))


def test_bad_truth(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    with McapWriter(path) as w:
        w.add_metadata("sofia.truth", {"json": "[1, 2"})
    with pytest.raises(BadTruthError, match=r"ground truth metadata of .* is invalid"):
        mcap_io.read_truth(path)
    with McapWriter(path) as w:
        w.write_cloud(TOPIC_POINTS, _cloud(0), T0)
    assert mcap_io.read_truth(path) is None
