"""ROS 1 bag -> MCAP: a real bag written with rosbags, converted, and read back intact."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from sofia_replay import mcap_io
from sofia_replay.convert import convert_bag, parse_topic_map
from sofia_replay.errors import BadBagError, BadMappingError, RecordingNotFoundError
from sofia_schemas import Keys, pointcloud, rosmsg
from sofia_schemas.keys import TOPIC_FLANGE_POSE, TOPIC_POINTS

from ..conftest import SOFIA

PC2 = "sensor_msgs/msg/PointCloud2"
T0 = 1_650_000_000_000_000_000
PERIOD = 50_000_000
# RealSense-like layout: x y z, 4 bytes padding, packed rgb, point_step 32
FIELDS = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("rgb", 16, 7)]
STEP = 32

ros1 = get_typestore(Stores.ROS1_NOETIC)
ros1.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
ros2 = get_typestore(Stores.ROS2_HUMBLE)


def _header(store: Any, i: int, frame_id: str) -> Any:
    T = store.types
    stamp = T["builtin_interfaces/msg/Time"](
        sec=(T0 + i * PERIOD) // 10**9, nanosec=(T0 + i * PERIOD) % 10**9
    )
    if store is ros1:
        return T["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id=frame_id)
    return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)


def _cloud_msg(store: Any, i: int, h: int = 4, w: int = 6, is_bigendian: bool = False) -> Any:
    T = store.types
    data = np.random.default_rng(i).integers(0, 256, h * w * STEP, dtype=np.uint8)
    return T[PC2](
        header=_header(store, i, "panda_link0"), height=h, width=w,
        fields=[T["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=1) for n, o, d in FIELDS],
        is_bigendian=is_bigendian, point_step=STEP, row_step=STEP * w, data=data, is_dense=False,
    )  # fmt: skip


def _transform(store: Any, i: int) -> Any:
    T = store.types
    return T["geometry_msgs/msg/TransformStamped"](
        header=_header(store, i, "panda_link0"),
        child_frame_id="panda_link8",
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=0.3, y=0.01 * i, z=0.6),
            rotation=T["geometry_msgs/msg/Quaternion"](x=1.0, y=0.0, z=0.0, w=0.0),
        ),
    )


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / "perception.bag"
    T = ros1.types
    with Writer(path) as w:
        pc = w.add_connection("/pc_glob", PC2, typestore=ros1)
        tool = w.add_connection("/tool_pose", "geometry_msgs/msg/TransformStamped", typestore=ros1)
        goal = w.add_connection("/goal", "geometry_msgs/msg/PoseStamped", typestore=ros1)
        tf = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=ros1)
        chat = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ros1)
        be = w.add_connection("/be_cloud", PC2, typestore=ros1)
        for i in range(6):
            t = T0 + i * PERIOD
            w.write(pc, t, ros1.serialize_ros1(_cloud_msg(ros1, i), PC2))
            w.write(
                tool, t + 1, ros1.serialize_ros1(_transform(ros1, i), "geometry_msgs/msg/TransformStamped")
            )
            w.write(
                chat,
                t + 2,
                ros1.serialize_ros1(T["std_msgs/msg/String"](data=f"hi {i}"), "std_msgs/msg/String"),
            )
        pose = T["geometry_msgs/msg/PoseStamped"](
            header=_header(ros1, 0, "panda_link0"),
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        w.write(goal, T0 + 3, ros1.serialize_ros1(pose, "geometry_msgs/msg/PoseStamped"))
        tfm = T["tf2_msgs/msg/TFMessage"](transforms=[_transform(ros1, 0), _transform(ros1, 1)])
        w.write(tf, T0 + 4, ros1.serialize_ros1(tfm, "tf2_msgs/msg/TFMessage"))
        w.write(be, T0 + 5, ros1.serialize_ros1(_cloud_msg(ros1, 99, is_bigendian=True), PC2))
    return path


def test_clouds_converted_byte_exact(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.mcap"
    report = convert_bag(bag, out, {"/tool_pose": TOPIC_FLANGE_POSE})

    assert report.written == {TOPIC_POINTS: 6, TOPIC_FLANGE_POSE: 6, "/goal": 1, "/tf": 1}
    assert report.skipped_topics == {"/chatter": "std_msgs/msg/String"}
    assert report.rejected == {"/be_cloud": 1}
    clouds = list(mcap_io.iter_messages(out, [TOPIC_POINTS]))
    for i, m in enumerate(clouds):
        # the ROS 2 message rosbags serializes from the same fields, independently of the converter
        assert m.data == bytes(ros2.serialize_cdr(_cloud_msg(ros2, i), PC2))
        assert m.log_time_ns == T0 + i * PERIOD
        cloud = pointcloud.decode(m.data)
        raw = np.asarray(_cloud_msg(ros1, i).data).reshape(4, 6, STEP)
        np.testing.assert_array_equal(cloud.xyz(), raw[:, :, :12].copy().view("<f4"))
        assert (cloud.stamp_ns, cloud.frame_id, cloud.point_step) == (T0 + i * PERIOD, "panda_link0", STEP)


def test_poses_tf_and_metadata(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.mcap"
    convert_bag(bag, out, {"/tool_pose": TOPIC_FLANGE_POSE})
    poses = list(mcap_io.iter_flange_poses(out))
    assert [p.translation for _, p in poses] == [(0.3, 0.01 * i, 0.6) for i in range(6)]
    assert poses[2][1].stamp_ns == T0 + 2 * PERIOD and poses[0][1].rotation_xyzw == (1.0, 0.0, 0.0, 0.0)
    s = mcap_io.summary(out)
    assert s.topics["/goal"].schema_name == "geometry_msgs/msg/PoseStamped"
    (goal,) = mcap_io.iter_messages(out, ["/goal"])
    assert ros2.deserialize_cdr(goal.data, "geometry_msgs/msg/PoseStamped").pose.position.z == 3.0
    (tf,) = mcap_io.iter_messages(out, ["/tf"])
    tfm = ros2.deserialize_cdr(tf.data, "tf2_msgs/msg/TFMessage")
    assert [t.transform.translation.y for t in tfm.transforms] == [0.0, 0.01]
    assert mcap_io.read_metadata(out)["sofia.source"]["bag"] == "perception.bag"


def test_only_topics(bag: Path, tmp_path: Path) -> None:
    report = convert_bag(bag, tmp_path / "o.mcap", topics=["/pc_glob"])
    assert report.written == {TOPIC_POINTS: 6}
    assert mcap_io.summary(tmp_path / "o.mcap").n_messages == 6


def test_cli(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "cli.mcap"
    run = subprocess.run(
        [SOFIA, "replay", "convert", str(bag), str(out), "--topic", f"/tool_pose={TOPIC_FLANGE_POSE}"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert f"{out}: 14 messages" in run.stdout
    assert "skipped /chatter (std_msgs/msg/String)" in run.stdout
    assert "rejected 1 messages of /be_cloud" in run.stdout
    assert "is_bigendian=True" in run.stderr  # the warning names why
    info = subprocess.run([SOFIA, "replay", "info", str(out)], capture_output=True, text=True, timeout=60)
    assert "/pc_glob" in info.stdout and "sensor_msgs/msg/PointCloud2" in info.stdout


def test_errors(tmp_path: Path) -> None:
    with pytest.raises(RecordingNotFoundError):
        convert_bag(tmp_path / "none.bag", tmp_path / "o.mcap")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\n" + b"\x07" * 100)
    with pytest.raises(BadBagError, match="is not a readable ROS 1 bag"):
        convert_bag(junk, tmp_path / "o.mcap")
    assert not (tmp_path / "o.mcap").exists()
    with pytest.raises(BadMappingError, match="expected SOURCE=TARGET"):
        parse_topic_map(["/a"])
    with pytest.raises(BadMappingError, match="mapped twice"):
        parse_topic_map(["/a=/b", "/a=/c"])
    run = subprocess.run(
        [SOFIA, "replay", "convert", str(junk), str(tmp_path / "o.mcap")], capture_output=True, text=True
    )
    assert run.returncode == 2 and "is not a readable ROS 1 bag" in run.stderr


def test_bag_converts_replays_and_arrives_intact(
    bag: Path, tmp_path: Path, sofia_proc: Callable[..., Any], collect: Callable[[str], Any], robot_id: str
) -> None:
    """The whole chain, each step its own process: ROS 1 bag -> MCAP -> Zenoh -> this subscriber."""
    out = tmp_path / "chain.mcap"
    conv = sofia_proc("replay", "convert", str(bag), str(out), "--topic", f"/tool_pose={TOPIC_FLANGE_POSE}")
    assert conv.popen.wait(60) == 0, conv.log()
    keys = Keys(robot_id)
    got = collect(keys.all)
    play = sofia_proc("replay", "play", str(out), "--rate", "5", "--wait-subscribers", "20")
    assert play.popen.wait(60) == 0, play.log()
    clouds = got.wait_for(keys.points, 6, timeout=10)
    assert [c.payload for c in clouds] == [
        bytes(ros2.serialize_cdr(_cloud_msg(ros2, i), PC2)) for i in range(6)
    ]
    poses = got.wait_for(keys.flange_pose, 6, timeout=10)
    assert [rosmsg.decode_flange_pose(p.payload).translation[1] for p in poses] == [
        0.01 * i for i in range(6)
    ]
    assert len(got.wait_for(f"sofia/{robot_id}/replay/tf", 1, timeout=5)) == 1
    assert len(got.wait_for(f"sofia/{robot_id}/replay/goal", 1, timeout=5)) == 1
