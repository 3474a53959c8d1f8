"""``sofia viz serve`` as a separate process: a Foxglove WebSocket client (foxglove.sdk.v1, the protocol spoken by
Foxglove, over ``websockets``) receives the advertised channels and decodes a cloud, a detection
and transforms logged from the bus."""

from __future__ import annotations

import json
import re
import struct
import time
from typing import Any

import numpy as np
import pytest
import zenoh
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas import pointcloud
from sofia_schemas.keys import ENCODING_CDR_POINTCLOUD2, ENCODING_JSON, Keys
from sofia_schemas.messages import CalibrationResult, DetectedObject, Detection, FlangePose
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.ros2.typesupport import decode
from sofia_schemas.rosmsg import encode_flange_pose
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from ..conftest import calibration_result

DEFAULT_T_FLANGE_CAM = np.array(
    [[0.0, -1.0, 0.0, 0.065], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.045], [0, 0, 0, 1.0]]
)
WANTED = ("/sofia/points", "/sofia/detections", "/tf", "/tf_static", "/sofia/scene")


def _calibration() -> CalibrationResult:
    return calibration_result(DEFAULT_T_FLANGE_CAM)


def test_foxglove_client_gets_channels_and_decodes(sofia_proc, robot_id: str) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    proc = sofia_proc("viz", "serve", "--port", "0")
    proc.wait_for_log("viz ready")
    port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", proc.log()).group(1))  # type: ignore[union-attr]
    cloud = pointcloud.encode_points(np.array([[0.5, 0.0, 0.1], [0.6, 0.1, 0.1]], np.float32), stamp_ns=11,
                                     frame_id="panda_link0")  # fmt: skip
    det = Detection(stamp_ns=11, frame_id="panda_link0", status="ok", objects=[DetectedObject(
        center=(0.5, 0.0, 0.03), centroid=(0.5, 0.0, 0.04), extents=(0.04, 0.04, 0.06), yaw=0.2, field=(1, 1),
        allowed=True, n_points=100, confidence=0.9)])  # fmt: skip
    flange = FlangePose(stamp_ns=11, translation=(0.4, 0.0, 0.5), rotation_xyzw=(1.0, 0.0, 0.0, 0.0))
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws, \
            zenoh.open(zenoh_config()) as session:  # fmt: skip
        channels = _advertised(ws, WANTED)
        assert channels["/sofia/points"]["schemaName"] == "sensor_msgs/msg/PointCloud2"
        assert channels["/sofia/points"]["encoding"] == "cdr"
        assert (
            channels["/tf"]["schemaName"] == channels["/tf_static"]["schemaName"] == "tf2_msgs/msg/TFMessage"
        )
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": channels[t]["id"]} for i, t in enumerate(WANTED)]}))  # fmt: skip
        time.sleep(0.5)
        got: dict[str, bytes] = {}
        deadline = time.monotonic() + 30
        while len(got) < len(WANTED) and time.monotonic() < deadline:
            session.put(keys.points, bytes(cloud), encoding=ENCODING_CDR_POINTCLOUD2)
            session.put(keys.detections, det.to_json_bytes(), encoding=ENCODING_JSON)
            session.put(keys.flange_pose, encode_flange_pose(flange))
            session.put(keys.calibration_result, _calibration().to_json_bytes(), encoding=ENCODING_JSON)
            _receive(ws, WANTED, got, 0.5)
    assert set(got) == set(WANTED), sorted(got)
    points = pointcloud.decode(got["/sofia/points"])
    assert points.frame_id == "panda_link0" and np.allclose(
        points.xyz().reshape(-1, 3), [[0.5, 0, 0.1], [0.6, 0.1, 0.1]]
    )
    assert Detection.model_validate_json(got["/sofia/detections"]) == det
    tf = decode(got["/tf"], cv.TF_MESSAGE).transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id, tf.transform.translation.z) == (
        "panda_link0",
        "panda_link8",
        0.5,
    )
    static = decode(got["/tf_static"], cv.TF_MESSAGE).transforms[0]
    assert (static.header.frame_id, static.child_frame_id) == ("panda_link8", "camera_color_optical_frame")
    assert np.isclose(static.transform.translation.x, DEFAULT_T_FLANGE_CAM[0, 3])
    assert len(got["/sofia/scene"]) > 0
    assert proc.stop() == 0 and "Traceback" not in proc.log()


def _receive(ws: Any, topics: tuple[str, ...], got: dict[str, bytes], seconds: float) -> None:
    """Read Foxglove message-data frames for up to ``seconds``: the first payload of each subscription
    id ``i`` (subscribed as ``topics[i]``) goes to ``got[topics[i]]``."""
    end = time.monotonic() + seconds
    while len(got) < len(topics) and time.monotonic() < end:
        try:
            msg = ws.recv(timeout=0.2)
        except TimeoutError:
            continue
        if isinstance(msg, bytes) and msg[0] == 1:
            sub_id, _log_time = struct.unpack_from("<IQ", msg, 1)
            got.setdefault(topics[sub_id], msg[13:])


def _advertised(ws: Any, topics: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    channels: dict[str, dict[str, Any]] = {}
    deadline = time.monotonic() + 20
    while not set(topics) <= set(channels) and time.monotonic() < deadline:
        msg = ws.recv(timeout=5)
        if isinstance(msg, str) and json.loads(msg).get("op") == "advertise":
            channels.update({c["topic"]: c for c in json.loads(msg)["channels"]})
    assert set(topics) <= set(channels), sorted(channels)
    return channels


def test_clients_of_either_subprotocol_joining_after_the_calibration_get_tf_static_and_calibration(
    sofia_proc, robot_id: str
) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    proc = sofia_proc("viz", "serve", "--port", "0")
    proc.wait_for_log("viz ready")
    port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", proc.log()).group(1))  # type: ignore[union-attr]
    latched = ("/tf_static", "/sofia/calibration")
    with zenoh.open(zenoh_config()) as session:
        status_key, logged = keys.status("viz"), 0
        deadline = time.monotonic() + 30
        while logged < 1 and time.monotonic() < deadline:  # the calibration, once, before any client
            session.put(keys.calibration_result, _calibration().to_json_bytes(), encoding=ENCODING_JSON)
            time.sleep(0.3)
            replies = list(session.get(status_key, timeout=2.0))
            if replies and replies[0].ok is not None:
                logged = json.loads(replies[0].ok.payload.to_bytes())["counters"]["logged"]
        assert logged >= 1
    # two clients in turn, each after the calibration: one of each subprotocol name (the same protocol)
    for subprotocol in ("foxglove.sdk.v1", "foxglove.websocket.v1"):
        with connect(f"ws://127.0.0.1:{port}", subprotocols=[subprotocol]) as ws:  # type: ignore[list-item]
            assert ws.subprotocol == subprotocol
            channels = _advertised(ws, latched)
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": i, "channelId": channels[t]["id"]} for i, t in enumerate(latched)]}))  # fmt: skip
            got: dict[str, bytes] = {}
            _receive(ws, latched, got, 3.0)
            assert set(got) == set(latched), (sorted(got), proc.log()[-1500:])
            static = decode(got["/tf_static"], cv.TF_MESSAGE).transforms[0]
            assert (static.header.frame_id, static.child_frame_id) == (
                "panda_link8",
                "camera_color_optical_frame",
            )
            assert CalibrationResult.model_validate_json(got["/sofia/calibration"]).stamp_ns == 7
    with pytest.raises(InvalidStatus, match="HTTP 400"):  # neither name: refused as before
        connect(f"ws://127.0.0.1:{port}", subprotocols=["other.v1"])  # type: ignore[list-item]
    assert proc.stop() == 0 and "Traceback" not in proc.log()
