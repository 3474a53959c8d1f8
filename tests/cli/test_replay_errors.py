"""Recordings that cannot be played or converted say why and exit 2, leaving nothing behind;
`replay play --loop` gives every loop fresh stamps unless told otherwise."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import threading
import time
from pathlib import Path

import pytest
import zenoh
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore
from sofia_replay.mcap_io import McapWriter
from sofia_replay.stamps import stamp_ns
from sofia_runtime.zenoh_config import open_session
from sofia_schemas import FlangePose, Keys
from sofia_schemas.keys import TOPIC_FLANGE_POSE

from ..conftest import SOFIA

T0 = 1_700_000_000_000_000_000
PERIOD = 50_000_000
N = 6
TF = "geometry_msgs/msg/TransformStamped"
ros1 = get_typestore(Stores.ROS1_NOETIC)


def sofia(*args: str, robot: str = "panda") -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, SOFIA_ROBOT=robot)
    return subprocess.run([SOFIA, *args], capture_output=True, text=True, timeout=300, env=env)


@pytest.fixture
def poses_mcap(tmp_path: Path) -> Path:
    path = tmp_path / "poses.mcap"
    with McapWriter(path) as w:
        for i in range(N):
            t = T0 + i * PERIOD
            pose = FlangePose(stamp_ns=t, translation=(0.4, 0.0, 0.5 + 0.01 * i), rotation_xyzw=(1, 0, 0, 0))
            w.write_flange_pose(TOPIC_FLANGE_POSE, pose, t)
    return path


def _tf(i: int) -> bytes:
    T = ros1.types
    msg = T[TF](
        header=T["std_msgs/msg/Header"](
            seq=i, stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=i), frame_id="panda_link0"
        ),
        child_frame_id="panda_link8",
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=0.3, y=0.0, z=0.6),
            rotation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
    )
    return bytes(ros1.serialize_ros1(msg, TF))


def test_play_an_unknown_topic_names_the_topics_there_are(poses_mcap: Path) -> None:
    r = sofia("replay", "play", str(poses_mcap), "--topic", "/nonexistent", "--fast")
    assert r.returncode == 2, r.stderr
    assert "has no topic /nonexistent (its topics: /sofia/flange_pose)" in r.stderr


def test_bags_with_nothing_to_convert(tmp_path: Path) -> None:
    empty, chatter, whole = tmp_path / "empty.bag", tmp_path / "chatter.bag", tmp_path / "whole.bag"
    with Writer(empty):
        pass
    with Writer(chatter) as w:
        c = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ros1)
        w.write(
            c,
            T0,
            bytes(ros1.serialize_ros1(ros1.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String")),
        )
    with Writer(whole) as w:
        c = w.add_connection("/tool_pose", TF, typestore=ros1)
        for i in range(200):
            w.write(c, T0 + i * PERIOD, _tf(i))
    truncated = tmp_path / "truncated.bag"
    truncated.write_bytes(whole.read_bytes()[: whole.stat().st_size * 9 // 10])  # a copy cut short
    cases = {
        empty: "the bag holds no message",
        chatter: "no topic of a converted type (skipped /chatter (std_msgs/msg/String)",
        truncated: "run `rosbag reindex truncated.bag`",
    }
    env = dict(os.environ)
    runs = {  # side by side, each its own process
        bag: subprocess.Popen([SOFIA, "replay", "convert", str(bag), str(tmp_path / f"{bag.stem}.mcap"), "--json"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        for bag in [*cases, whole]
    }  # fmt: skip
    for bag, p in runs.items():
        out, err = p.communicate(timeout=300)
        mcap = tmp_path / f"{bag.stem}.mcap"
        if bag is whole:
            assert p.returncode == 0 and json.loads(out)["written"] == {"/tool_pose": 200}, out + err
            continue
        assert p.returncode == 2 and cases[bag] in err, (bag.name, out, err)
        assert not mcap.exists(), f"{bag.name}: {mcap.name} left behind"


def test_loop_restamps_by_default(poses_mcap: Path, robot_id: str) -> None:
    key = Keys(robot_id).flange_pose
    stamps: list[int] = []
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        with lock:
            stamps.append(stamp_ns(sample.payload.to_bytes()))

    env = dict(os.environ, SOFIA_ROBOT=robot_id)
    with open_session() as session:
        session.declare_subscriber(key, on_sample)
        play = subprocess.Popen(
            [SOFIA, "replay", "play", str(poses_mcap), "--loop", "--rate", "4", "--wait-subscribers", "30"],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and len(stamps) < 2 * N + 1 and play.poll() is None:
                time.sleep(0.05)
        finally:
            play.terminate()
            _, err = play.communicate(timeout=60)
    with lock:
        got = list(stamps)
    assert len(got) >= 2 * N + 1, err  # more than two loops
    assert all(b > a for a, b in itertools.pairwise(got)), "a stamp jumped back between loops"
    assert abs(got[-1] - time.time_ns()) < 120e9  # wall-clock stamps, not the recorded ones
