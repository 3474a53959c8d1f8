"""``sofia camera record``: the camera's clouds and camera info, and the flange poses when an arm
publishes them, from the bus into an MCAP file the replayer plays (``sofia replay play``).

Topics: clouds on ``/camera/depth/color/points``, camera info on ``/camera/color/camera_info``,
flange poses on ``/sofia/flange_pose`` (CDR TransformStamped), log time = each message's stamp.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from pathlib import Path

import zenoh
from sofia_replay.mcap_io import McapWriter
from sofia_runtime.zenoh_config import ZenohOptions, zenoh_config
from sofia_schemas import pointcloud
from sofia_schemas.keys import TOPIC_CAMERA_INFO, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE, Keys
from sofia_schemas.rosmsg import decode_flange_pose

from .camera_info import CAMERA_INFO, decode_camera_info

log = logging.getLogger(__name__)
BACKLOG_BYTES = 300_000_000  # waiting for the writer (about 2 s of 1280x720 clouds); more is dropped


def _write(writer: McapWriter, kind: str, payload: bytes) -> None:
    if kind == "clouds":
        stamp = pointcloud.decode(payload).stamp_ns
        writer.write_cloud(TOPIC_CAMERA_POINTS, payload, stamp)
    elif kind == "camera_info":
        h = decode_camera_info(payload).header.stamp
        writer.write_raw(TOPIC_CAMERA_INFO, CAMERA_INFO, payload, h.sec * 1_000_000_000 + h.nanosec)
    else:
        writer.write_flange_pose(TOPIC_FLANGE_POSE, decode_flange_pose(payload))


def record(
    out: Path, seconds: float, robot: str, zenoh_options: ZenohOptions | None = None
) -> dict[str, int]:
    """Record for ``seconds``; returns how many clouds, camera infos and flange poses were written
    (and how many messages were dropped or unreadable)."""
    keys = Keys(robot)
    inbox: queue.Queue[tuple[str, bytes] | None] = queue.Queue()
    backlog = [0]  # bytes handed over and not yet written
    lock = threading.Lock()
    counts = {"clouds": 0, "camera_info": 0, "flange_poses": 0, "dropped": 0, "unreadable": 0}

    def hand_over(kind: str):  # type: ignore[no-untyped-def]
        def callback(sample: zenoh.Sample) -> None:
            payload = sample.payload.to_bytes()
            with lock:
                if backlog[0] + len(payload) > BACKLOG_BYTES:
                    counts["dropped"] += 1
                    return
                backlog[0] += len(payload)
            inbox.put((kind, payload))

        return callback

    def write_all(writer: McapWriter) -> None:
        while (item := inbox.get()) is not None:
            kind, payload = item
            with lock:
                backlog[0] -= len(payload)
            try:
                _write(writer, kind, payload)
            except ValueError as e:
                counts["unreadable"] += 1
                log.warning("%s message not recorded: %s", kind, e)
                continue
            counts[kind] += 1

    with McapWriter(out, compression="lz4") as writer, zenoh.open(zenoh_config(zenoh_options)) as session:
        worker = threading.Thread(target=write_all, args=(writer,), name="camera-record", daemon=True)
        worker.start()
        subs = [session.declare_subscriber(keys.camera_points, hand_over("clouds")),
                session.declare_subscriber(keys.camera_info, hand_over("camera_info")),
                session.declare_subscriber(keys.flange_pose, hand_over("flange_poses"))]  # fmt: skip
        time.sleep(seconds)
        for sub in subs:
            sub.undeclare()
        inbox.put(None)
        worker.join()
    log.info("recorded %s to %s", counts, out)
    return counts
