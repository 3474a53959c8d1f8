"""``sofia viz serve``: a Foxglove WebSocket server fed from the bus, for the live view in Foxglove.

Channels (topic, encoding):

==========================  ======================================================================
``/sofia/points``           CDR ``sensor_msgs/msg/PointCloud2`` (``ros2msg`` schema), base frame
``/sofia/camera/points``    CDR ``sensor_msgs/msg/PointCloud2``, camera optical frame
``/tf``                     CDR ``tf2_msgs/msg/TFMessage``: base -> flange from the flange pose
``/tf_static``              CDR ``tf2_msgs/msg/TFMessage``: flange -> camera from the calibration
``/sofia/scene``            ``foxglove.SceneUpdate``: board and fields, detected boxes, centres and
                            centroids, pick target, mapped calibration blob
``/sofia/detections``       JSON :class:`~sofia_schemas.Detection`
``/sofia/pick_target``      JSON :class:`~sofia_schemas.PickTarget`
``/sofia/calibration``      JSON :class:`~sofia_schemas.CalibrationResult`
``/sofia/gripper/state``    JSON :class:`~sofia_schemas.GripperState` (plot the opening, force)
==========================  ======================================================================

Clients connect to ``--host``/``--port`` with the subprotocol ``foxglove.sdk.v1`` or
``foxglove.websocket.v1`` (:mod:`sofia_viz.subprotocols`, in front of the SDK's server).

The saved layout ``sofia_viz/data/layout.json`` (3D panel in the base frame, plots, raw messages)
opens these in Foxglove: Layouts -> Import from file.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import foxglove
import zenoh
from foxglove.channels import SceneUpdateChannel
from foxglove.messages import SceneEntityDeletion, SceneEntityDeletionType, SceneUpdate
from sofia_runtime.client import fetch_latest
from sofia_runtime.service import StatusEndpoint, StopFlag, run_worker, serve
from sofia_runtime.zenoh_config import ZenohOptions, zenoh_config
from sofia_schemas import Board
from sofia_schemas.frames import CAMERA_FRAME
from sofia_schemas.keys import Keys
from sofia_schemas.messages import (
    CalibrationResult,
    Detection,
    GripperState,
    PickTarget,
    ServiceStatus,
    now_ns,
)
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.ros2.encoding import decode_flange
from sofia_schemas.ros2.typesupport import encode
from sofia_schemas.rosmsg import msgdef

from .errors import PortInUse
from .scene import board_entity, calibration_entity, detection_entities, pick_entity
from .subprotocols import SubprotocolFront

log = logging.getLogger("sofia.viz")
MAX_OBJECTS = 8  # scene entities object/<i> cleared beyond the detection's objects
LATCH_DELAY_S = 0.05  # after a subscription, before its latched message is logged again


@dataclass
class ServiceConfig:
    robot: str
    zenoh: ZenohOptions
    board: Board
    host: str = "127.0.0.1"
    port: int = 8765
    camera_frame: str = CAMERA_FRAME


def ros2_channel(topic: str, typename: str) -> foxglove.Channel:
    schema = foxglove.Schema(name=typename, encoding="ros2msg", data=msgdef(typename).encode())
    return foxglove.Channel(topic, message_encoding="cdr", schema=schema)


def json_channel(topic: str, model: Any) -> foxglove.Channel:
    return foxglove.Channel(topic, schema=model.model_json_schema())


class LateJoiners(foxglove.ServerListener):
    """Hands each new subscription's topic over to :meth:`Viz.replay_latched` (on its own thread)."""

    def __init__(self) -> None:
        self.topics: queue.Queue[str | None] = queue.Queue()

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.topics.put(str(channel.topic))


class Viz:
    """Zenoh samples -> Foxglove channels (the callbacks only convert and log).

    Latched topics (``/tf_static``, ``/sofia/calibration``): their last message is logged again
    whenever a client subscribes, so a client that joins after the calibration can place the
    camera clouds at once (the SDK cannot send to one client: the others get a duplicate)."""

    def __init__(self, config: ServiceConfig) -> None:
        self.config = config
        self.latched: dict[str, tuple[foxglove.Channel, bytes | str]] = {}
        self._lock = threading.Lock()
        self.counters = {"logged": 0, "errors": 0, "latched": 0}
        self.last_error = ""
        self.points = ros2_channel("/sofia/points", cv.POINTCLOUD2)
        self.camera = ros2_channel("/sofia/camera/points", cv.POINTCLOUD2)
        self.tf = ros2_channel("/tf", cv.TF_MESSAGE)
        self.tf_static = ros2_channel("/tf_static", cv.TF_MESSAGE)
        self.scene = SceneUpdateChannel("/sofia/scene")
        self.json = {
            "det": json_channel("/sofia/detections", Detection),
            "pick": json_channel("/sofia/pick_target", PickTarget),
            "calib": json_channel("/sofia/calibration", CalibrationResult),
            "gripper": json_channel("/sofia/gripper/state", GripperState),
        }

    def _guard(self, what: str, fn: Callable[[zenoh.Sample], None]) -> Callable[[zenoh.Sample], None]:
        def handler(sample: zenoh.Sample) -> None:
            try:
                fn(sample)
                self.counters["logged"] += 1
            except ValueError as e:
                self.counters["errors"] += 1
                self.last_error = f"{what}: {e}"
                log.warning("%s", self.last_error)

        return handler

    def on_points(self, sample: zenoh.Sample) -> None:
        self.points.log(sample.payload.to_bytes())

    def on_camera(self, sample: zenoh.Sample) -> None:
        self.camera.log(sample.payload.to_bytes())

    def on_flange(self, sample: zenoh.Sample) -> None:
        pose = decode_flange(sample.payload.to_bytes(), sample.encoding)
        self.tf.log(encode(cv.tf_message([cv.flange_transform(pose)]), cv.TF_MESSAGE))

    def on_detection(self, sample: zenoh.Sample) -> None:
        raw = sample.payload.to_bytes()
        det = Detection.model_validate_json(raw)
        self.json["det"].log(raw.decode())
        entities = detection_entities(det)
        stale = [SceneEntityDeletion(type=SceneEntityDeletionType.MatchingId, id=f"object/{i}")
                 for i in range(len(entities), MAX_OBJECTS)]  # fmt: skip
        self.scene.log(SceneUpdate(deletions=stale, entities=entities))

    def on_pick(self, sample: zenoh.Sample) -> None:
        raw = sample.payload.to_bytes()
        self.json["pick"].log(raw.decode())
        self.scene.log(SceneUpdate(entities=[pick_entity(PickTarget.model_validate_json(raw))]))

    def on_calibration(self, sample: zenoh.Sample) -> None:
        raw = sample.payload.to_bytes()
        result = CalibrationResult.model_validate_json(raw)
        tf = encode(
            cv.tf_message([cv.calibration_transform(result, self.config.camera_frame)]), cv.TF_MESSAGE
        )
        with self._lock:
            self.latched["/sofia/calibration"] = (self.json["calib"], raw.decode())
            self.latched["/tf_static"] = (self.tf_static, tf)
        self.json["calib"].log(raw.decode())
        self.tf_static.log(tf)
        self.scene.log(SceneUpdate(entities=[calibration_entity(result, self.config.board.frame_id)]))

    def on_gripper(self, sample: zenoh.Sample) -> None:
        raw = sample.payload.to_bytes()
        GripperState.model_validate_json(raw)
        self.json["gripper"].log(raw.decode())

    def replay_latched(self, topics: queue.Queue[str | None]) -> None:
        """Log the latched message of each newly subscribed topic again, until None arrives. A
        subscription is taken once the listener returns: the message follows it shortly after."""
        while (topic := topics.get()) is not None:
            with self._lock:
                latched = self.latched.get(topic)
            if latched is not None:
                time.sleep(LATCH_DELAY_S)
                latched[0].log(latched[1])
                self.counters["latched"] += 1

    def publish_board(self) -> None:
        self.scene.log(SceneUpdate(entities=[board_entity(self.config.board, now_ns())]))


def main(config: ServiceConfig) -> int:
    """Run until SIGINT/SIGTERM."""
    stop = StopFlag()
    keys = Keys(config.robot)
    viz = Viz(config)
    joiners = LateJoiners()
    # the SDK's server on a loopback port, behind the front that also takes foxglove.websocket.v1 clients
    server = foxglove.start_server(
        name=f"sofia {config.robot}", host="127.0.0.1", port=0, server_listener=joiners
    )
    try:
        front = SubprotocolFront(config.host, config.port, server.port)
    except OSError as e:
        server.stop()
        raise PortInUse(config.host, config.port, e.strerror or str(e)) from None
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        subs = [
            session.declare_subscriber(key, viz._guard(what, fn))
            for key, what, fn in (
                (keys.points, "points", viz.on_points), (keys.camera_points, "camera points", viz.on_camera),
                (keys.flange_pose, "flange pose", viz.on_flange), (keys.detections, "detection", viz.on_detection),
                (keys.pick_target, "pick target", viz.on_pick),
                (keys.calibration_result, "calibration", viz.on_calibration),
                (keys.gripper_state, "gripper state", viz.on_gripper),
            )
        ]  # fmt: skip
        replayer = run_worker("viz-latched", lambda: viz.replay_latched(joiners.topics))
        # the calibration solved before this process started, if a calibrator answers
        fetching = fetch_latest(session, keys.calibration_result, viz._guard("calibration", viz.on_calibration),
                                stop.event, timeout=5.0)  # fmt: skip

        def status() -> ServiceStatus:
            return ServiceStatus(service="viz", stamp_ns=now_ns(), state="ok", detail=viz.last_error,
                                 counters=dict(viz.counters), info={"foxglove": f"ws://{config.host}:{front.port}", "board": config.board.digest})  # fmt: skip

        endpoint = StatusEndpoint(session, keys.status("viz"), status)
        log.info(
            "viz ready: Foxglove WebSocket on ws://%s:%d (robot %s)", config.host, front.port, config.robot
        )
        code = serve(stop, endpoint, [replayer], name="viz", log=log, declared=subs, also_join=[fetching],
                     on_stop=[lambda: joiners.topics.put(None)], each_period=[viz.publish_board])  # fmt: skip
    front.stop()
    server.stop()
    return code
