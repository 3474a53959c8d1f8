"""`sofia replay play --preload` (a separate process): the messages played from memory, byte-identical
to the recording, and with --restamp every put carries its own fresh stamp; clouds to a local
subscriber travel through Zenoh's shared memory unless ``SOFIA_ZENOH_SHM=off``."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import zenoh
from sofia_replay.stamps import stamp_ns
from sofia_runtime.shm import SharedReader
from sofia_runtime.zenoh_config import open_session
from sofia_schemas import Keys
from sofia_schemas.keys import TOPIC_CAMERA_POINTS, TOPIC_POINTS

from .test_play import N, recording  # noqa: F401 - the fixture


def test_preloaded_replay_is_byte_identical(
    recording: tuple[Path, dict[str, list[bytes]]],  # noqa: F811
    sofia_proc: Callable[..., Any], collect: Callable[[str], Any], robot_id: str,
) -> None:  # fmt: skip
    path, written = recording
    keys = Keys(robot_id)
    got = collect(keys.all)
    proc = sofia_proc("replay", "play", str(path), "--fast", "--preload", "--wait-subscribers", "20")
    assert proc.popen.wait(60) == 0, proc.log()
    for key, topic in ((keys.points, TOPIC_POINTS), (keys.camera_points, TOPIC_CAMERA_POINTS)):
        received = got.wait_for(key, N, timeout=10)
        assert [r.payload for r in received] == written[topic], key  # the recorded stamps and bytes
    assert f"preloaded {4 * N + 1} messages" in proc.log()


def test_preloaded_loop_restamps_each_put(
    recording: tuple[Path, dict[str, list[bytes]]],  # noqa: F811
    sofia_proc: Callable[..., Any], collect: Callable[[str], Any], robot_id: str,
) -> None:  # fmt: skip
    """The preloaded buffers are restamped in place: every cloud received (three loops) has its own
    stamp, increasing, near the wall clock, and the rest of its bytes as recorded."""
    path, written = recording
    keys = Keys(robot_id)
    got = collect(keys.points)
    proc = sofia_proc("replay", "play", str(path), "--rate", "4", "--loop", "--preload", "--topic", TOPIC_POINTS,
                      "--wait-subscribers", "20")  # fmt: skip
    received = got.wait_for(keys.points, 3 * N, timeout=60)[: 3 * N]
    assert proc.stop() == 0
    assert len(received) == 3 * N
    stamps = [stamp_ns(r.payload) for r in received]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    assert abs(stamps[-1] - time.time_ns()) < 30e9  # the publish time, not the recorded one
    recorded = written[TOPIC_POINTS] * 3
    assert all(
        r.payload[12:] == w[12:] and r.payload[:4] == w[:4] for r, w in zip(received, recorded, strict=True)
    )


@pytest.mark.parametrize("shm", ["on", "off"])
def test_clouds_reach_a_local_subscriber_through_shared_memory(
    recording: tuple[Path, dict[str, list[bytes]]],  # noqa: F811
    sofia_proc: Callable[..., Any], robot_id: str, shm: str,
) -> None:  # fmt: skip
    """By default the replayer writes each cloud into Zenoh shared memory and a local subscriber maps
    it (no copy through the socket) and reads it in place where the replayer's attachment says it
    lies; ``SOFIA_ZENOH_SHM=off`` in the replayer's environment sends them over the socket."""
    path, written = recording
    keys = Keys(robot_id)
    via_shm: list[bool] = []
    payloads: list[bytes] = []
    in_place: list[bytes | None] = []
    reader = SharedReader()

    def on_cloud(sample: zenoh.Sample) -> None:
        via_shm.append(sample.payload.as_shm() is not None)
        view = reader.view(sample.payload, sample.attachment.to_bytes() if sample.attachment else None)
        in_place.append(None if view is None else view.tobytes())
        payloads.append(sample.payload.to_bytes())

    with open_session() as session:
        session.declare_subscriber(keys.points, on_cloud)
        proc = sofia_proc("replay", "play", str(path), "--preload", "--topic", TOPIC_POINTS,
                          "--wait-subscribers", "20", env={"SOFIA_ZENOH_SHM": shm})  # fmt: skip
        assert proc.popen.wait(60) == 0, proc.log()
        deadline = time.monotonic() + 10
        while len(payloads) < N and time.monotonic() < deadline:
            time.sleep(0.02)
    assert payloads == written[TOPIC_POINTS]
    if shm == "off":
        assert not any(via_shm) and in_place == [None] * N
    else:  # written into shared memory from the first put on (a full pool would fall back to bytes)
        assert via_shm[0] and sum(via_shm) >= N - 1, via_shm
        read = [(v, p) for v, p in zip(in_place, payloads, strict=True) if v is not None]
        assert len(read) >= N - 1 and all(v == p for v, p in read) and reader.copied == 0, reader.reason
