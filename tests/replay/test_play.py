"""`sofia replay play` as a separate process; this test subscribes over Zenoh and checks every byte."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from sofia_replay.errors import RecordingError
from sofia_replay.mcap_io import McapWriter
from sofia_replay.player import default_key, encoding_of
from sofia_replay.stamps import restamp, stamp_ns
from sofia_schemas import BlobObservation, FlangePose, Keys, ServiceStatus, pointcloud
from sofia_schemas.keys import (
    ENCODING_CDR_POINT,
    ENCODING_CDR_POINTCLOUD2,
    ENCODING_CDR_TRANSFORM,
    TOPIC_BLOB,
    TOPIC_CAMERA_POINTS,
    TOPIC_FLANGE_POSE,
    TOPIC_POINTS,
)

T0 = 1_700_000_000_000_000_000
PERIOD = 50_000_000  # 20 Hz
N = 8
POSE = "geometry_msgs/msg/PoseStamped"


def _extra_pose(i: int) -> bytes:
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    msg = T[POSE](
        header=T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="map"
        ),
        pose=T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(i), y=0.0, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
    )
    return bytes(ts.serialize_cdr(msg, POSE))


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, list[bytes]]]:
    """A synthetic recording and, per topic, the bytes written (in order)."""
    path = tmp_path_factory.mktemp("rec") / "synthetic.mcap"
    written: dict[str, list[bytes]] = {}
    rng = np.random.default_rng(7)
    with McapWriter(path) as w:
        for i in range(N):
            t = T0 + i * PERIOD
            p = rng.normal(size=(48, 64, 3)).astype(np.float32)
            p[0, :5] = np.nan
            rgb = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
            cloud = bytes(pointcloud.encode_points(p, stamp_ns=t, frame_id="panda_link0", rgb=rgb))
            cam = bytes(pointcloud.encode_points(p.reshape(-1, 3)[:500], stamp_ns=t, frame_id="cam"))
            pose = FlangePose(stamp_ns=t, translation=(0.4, 0.0, 0.5 + 0.01 * i), rotation_xyzw=(1, 0, 0, 0))
            w.write_cloud(TOPIC_POINTS, cloud, t)
            w.write_cloud(TOPIC_CAMERA_POINTS, cam, t + 1)
            w.write_flange_pose(TOPIC_FLANGE_POSE, pose, t + 2)
            w.write_raw("/extra/goal", POSE, _extra_pose(i), t + 3)
            written.setdefault(TOPIC_POINTS, []).append(cloud)
            written.setdefault(TOPIC_CAMERA_POINTS, []).append(cam)
            written.setdefault("/extra/goal", []).append(_extra_pose(i))
        blob = BlobObservation(stamp_ns=T0 + PERIOD, position=(0.0, 0.01, 0.4))
        w.write_blob(TOPIC_BLOB, blob, T0 + PERIOD + 4)
    from sofia_replay.mcap_io import iter_messages

    for m in iter_messages(path, [TOPIC_FLANGE_POSE, TOPIC_BLOB]):
        written.setdefault(m.topic, []).append(m.data)
    return path, written


@dataclass
class Play:
    """The recording, its bytes per topic, the test's keys, a subscriber factory and ``run(*args)``:
    ``sofia replay play RECORDING *args`` as a process."""

    path: Path
    written: dict[str, list[bytes]]
    keys: Keys
    collect: Callable[[str], Any]
    sofia_proc: Callable[..., Any]

    def run(self, *args: str) -> Any:
        return self.sofia_proc("replay", "play", str(self.path), *args)


@pytest.fixture
def play(
    recording: tuple[Path, dict[str, list[bytes]]], sofia_proc: Callable[..., Any],
    collect: Callable[[str], Any], robot_id: str,
) -> Play:  # fmt: skip
    return Play(*recording, Keys(robot_id), collect, sofia_proc)


def _statuses(samples: list[Any]) -> list[ServiceStatus]:
    return [ServiceStatus.model_validate_json(s.payload) for s in samples]


def test_default_key_map() -> None:
    k = Keys("r1")
    assert default_key(k, TOPIC_POINTS) == "sofia/r1/points"
    assert default_key(k, "/extra//goal/") == "sofia/r1/replay/extra/goal"
    assert encoding_of("sensor_msgs/msg/PointCloud2") == ENCODING_CDR_POINTCLOUD2
    assert encoding_of(POSE) == "application/cdr;geometry_msgs/msg/PoseStamped"


def test_every_message_received_intact(play: Play) -> None:
    written, keys = play.written, play.keys
    got = play.collect(keys.all)
    proc = play.run("--fast", "--wait-subscribers", "20")
    assert proc.popen.wait(60) == 0, proc.log()

    expected = {
        keys.points: (written[TOPIC_POINTS], ENCODING_CDR_POINTCLOUD2),
        keys.camera_points: (written[TOPIC_CAMERA_POINTS], ENCODING_CDR_POINTCLOUD2),
        keys.flange_pose: (written[TOPIC_FLANGE_POSE], ENCODING_CDR_TRANSFORM),
        keys.blob: (written[TOPIC_BLOB], ENCODING_CDR_POINT),
        f"{keys.prefix}/replay/extra/goal": (written["/extra/goal"], "application/cdr;" + POSE),
    }
    for key, (payloads, encoding) in expected.items():
        received = got.wait_for(key, len(payloads), timeout=10)
        assert [r.payload for r in received] == payloads, key  # byte-identical, in order
        assert {r.encoding for r in received} == {encoding}
    cloud = pointcloud.decode(got.on(keys.points)[3].payload)
    assert cloud.shape == (48, 64) and cloud.stamp_ns == T0 + 3 * PERIOD

    time.sleep(0.2)
    statuses = _statuses(got.on(keys.status("replay")))
    assert statuses[0].state == "starting" and statuses[-1].state == "stopping"
    final = statuses[-1].counters
    assert final["published"] == 4 * N + 1
    assert final[f"topic:{TOPIC_POINTS}"] == N and final[f"topic:{TOPIC_BLOB}"] == 1
    assert final["bytes"] == sum(len(p) for ps in written.values() for p in ps)
    assert "replay done" in proc.log()


def test_recorded_rate_window_and_mapping(play: Play) -> None:
    """--rate 0.5 over clouds 2..5 of the recording (--start/--end), remapped to another key and
    restamped: the stamps are the publish times, so the pacing is the player's, not the delivery's
    (the first sample of a new publisher can arrive tens of ms late on a loaded machine)."""
    keys = play.keys
    key = f"{keys.prefix}/custom/cloud"
    got = play.collect(keys.all)
    launched_ns = time.time_ns()
    proc = play.run(
        "--rate", "0.5", "--start", "0.1", "--end", "0.26", "--restamp",
        "--topic", TOPIC_POINTS, "--map", f"{TOPIC_POINTS}={key}", "--wait-subscribers", "20",
    )  # fmt: skip
    assert proc.popen.wait(60) == 0, proc.log()
    received = got.wait_for(key, 4, timeout=5)
    published_ns = np.array([stamp_ns(r.payload) for r in received])
    assert [r.payload for r in received] == [
        restamp(w, t) for w, t in zip(play.written[TOPIC_POINTS][2:6], published_ns, strict=True)
    ]  # only the stamps rewritten
    assert got.on(keys.points) == [] and got.on(keys.flange_pose) == []
    assert launched_ns < published_ns[0] <= time.time_ns()
    # 3 periods of 50 ms at half speed: 0.1 s apart (1.0 would give 0.05). One late put shortens one
    # gap and lengthens the next; the first put also creates the shared-memory pool (a few ms)
    gaps_s = np.diff(published_ns) / 1e9
    assert 0.095 <= np.median(gaps_s) <= 0.15, gaps_s
    assert 0.25 <= (published_ns[-1] - published_ns[0]) / 1e9 < 2.0, gaps_s


def test_loop_until_stopped(play: Play) -> None:
    keys = play.keys
    got = play.collect(keys.all)
    proc = play.run(
        "--rate", "4", "--loop", "--no-restamp", "--topic", TOPIC_FLANGE_POSE, "--wait-subscribers", "20"
    )
    received = got.wait_for(keys.flange_pose, 2 * N + 1, timeout=30)
    assert proc.stop() == 0
    assert len(received) >= 2 * N + 1
    assert [r.payload for r in received[: 2 * N]] == play.written[TOPIC_FLANGE_POSE] * 2
    assert "stopped" in proc.log()
    time.sleep(0.2)
    last = _statuses(got.on(keys.status("replay")))[-1]
    assert last.state == "stopping" and last.counters["loops"] >= 2


def test_loop_keeps_the_frame_period_across_the_wrap(play: Play) -> None:
    """A loop's first message follows the previous loop's last by one period (100 ms at --rate 0.5),
    not at once: two clouds in a burst would make a detector with backlog 1 drop one."""
    keys = play.keys
    got = play.collect(keys.flange_pose)
    proc = play.run("--rate", "0.5", "--loop", "--topic", TOPIC_FLANGE_POSE, "--wait-subscribers", "20")
    received = got.wait_for(keys.flange_pose, N + 2, timeout=30)
    assert proc.stop() == 0
    gaps = np.diff([r.t for r in received[: N + 2]])
    wrap = gaps[N - 1]  # last message of loop 1 -> first of loop 2
    assert wrap > 0.05, (wrap, gaps)  # one period (0.1 s) less scheduling jitter; at once it was < 2 ms
    assert wrap < 0.5, (wrap, gaps)


@pytest.mark.parametrize(
    "args,message",
    [
        (["missing.mcap"], "recording 'missing.mcap' does not exist"),
        (["REC", "--rate", "0"], "--rate must be a positive finite multiplier, got 0.0"),
        (["REC", "--map", "/pc_glob=sofia/*/points"], "must not contain wildcards"),
        (["REC", "--map", "/pc_glob"], "expected SOURCE=TARGET"),
        (["REC", "--start", "0.3", "--end", "0.1"], "--end 0.1 s must be after --start 0.3 s"),
    ],
)
def test_bad_arguments(
    recording: tuple[Path, dict[str, list[bytes]]],
    sofia_proc: Callable[..., Any],
    args: list[str],
    message: str,
) -> None:
    args = [str(recording[0]) if a == "REC" else a for a in args]
    proc = sofia_proc("replay", "play", *args)
    assert proc.popen.wait(30) == 2
    assert message in proc.log()


def test_info_json(recording: tuple[Path, dict[str, list[bytes]]], sofia_proc: Callable[..., Any]) -> None:
    proc = sofia_proc("replay", "info", str(recording[0]), "--json")
    assert proc.popen.wait(30) == 0
    info = json.loads(proc.log())
    assert info["n_messages"] == 4 * N + 1
    assert info["topics"]["/extra/goal"] == {"schema": POSE, "encoding": "cdr", "count": N}


STALLED_SUBSCRIBER = """
import sys, time
from sofia_runtime.zenoh_config import open_session
with open_session() as s:
    sub = s.declare_subscriber(sys.argv[1], lambda sample: None)
    print("ready", flush=True)
    time.sleep(120)
"""


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError(f"no VmRSS for {pid}")


@pytest.mark.slow
def test_stalled_subscriber_does_not_grow_memory(
    sofia_proc: Callable[..., Any], robot_id: str, tmp_path: Path
) -> None:
    """A subscriber process frozen with SIGSTOP: the replayer's memory stays flat and it keeps going."""
    import signal
    import subprocess
    import sys

    path = tmp_path / "big.mcap"
    rng = np.random.default_rng(0)
    with McapWriter(path) as w:
        for i in range(10):
            p = rng.normal(size=(480, 640, 3)).astype(np.float32)
            w.write_cloud(
                TOPIC_POINTS, pointcloud.encode_points(p, stamp_ns=i, frame_id="f"), T0 + i * PERIOD
            )
    sub = subprocess.Popen(
        [sys.executable, "-c", STALLED_SUBSCRIBER, Keys(robot_id).points], stdout=subprocess.PIPE
    )
    try:
        assert sub.stdout is not None and sub.stdout.readline().strip() == b"ready"
        proc = sofia_proc(
            "replay", "play", str(path), "--fast", "--loop", "--wait-subscribers", "20", "--progress", "1"
        )
        proc.wait_for_log("published", timeout=30)
        sub.send_signal(signal.SIGSTOP)
        rss = []
        for _ in range(12):
            time.sleep(1.0)
            rss.append(_rss_mb(proc.popen.pid))
        assert max(rss) - min(rss) < 100, rss  # 10 s of 4 MB clouds at full speed would be gigabytes
        n_logs = proc.log().count("published")
        time.sleep(2.5)
        assert proc.log().count("published") > n_logs, "the replayer stopped making progress"
        assert proc.stop() == 0
    finally:
        sub.send_signal(signal.SIGCONT)
        sub.kill()
        sub.wait(10)


def test_restamp_rewrites_only_the_header_stamp() -> None:
    cdr = bytes(
        pointcloud.encode_points(np.zeros((4, 3), np.float32), stamp_ns=1_000_000_123, frame_id="panda_link0")
    )
    out = restamp(cdr, 1_795_000_000_987_654_321)
    assert stamp_ns(out) == 1_795_000_000_987_654_321 and stamp_ns(cdr) == 1_000_000_123
    assert out[:4] == cdr[:4] and out[12:] == cdr[12:] and len(out) == len(cdr)
    with pytest.raises(RecordingError, match="little-endian CDR"):
        restamp(b"\x00\x00\x00\x00" + cdr[4:], 0)


def test_status_query_and_restamped_loop(play: Play) -> None:
    """`sofia health replay` answers while playing; --restamp gives every loop fresh stamps."""
    keys = play.keys
    got = play.collect(keys.flange_pose)
    play.run("--rate", "4", "--loop", "--restamp", "--topic", TOPIC_FLANGE_POSE, "--wait-subscribers", "20")
    received = got.wait_for(keys.flange_pose, 2 * N, timeout=30)
    health = play.sofia_proc("health", "replay")
    assert health.popen.wait(30) == 0, health.log()
    assert "replay: ok" in health.log()
    stamps = [stamp_ns(r.payload) for r in received]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)  # no stamp repeats across loops
    assert abs(stamps[-1] - time.time_ns()) < 30e9  # the publish time, not the recorded one
