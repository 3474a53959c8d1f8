"""SofIA's keys offered to ROS 2 the way rmw_zenoh offers topics and services, and ROS 2 inputs
taken into SofIA: one node per SofIA service, in one process (``sofia ros2 serve``).

Out (SofIA key -> ROS 2 topic, type):

=====================================  ===================================  ====================================
``sofia/{robot}/points``               ``/sofia/{robot}/points``            ``sensor_msgs/msg/PointCloud2``
``sofia/{robot}/camera/points``        ``/sofia/{robot}/camera/points``     ``sensor_msgs/msg/PointCloud2``
``sofia/{robot}/detector/detections``  ``/sofia/{robot}/detections``        ``vision_msgs/msg/Detection3DArray``
``sofia/{robot}/pick/target``          ``/sofia/{robot}/pick_target``,      ``geometry_msgs/msg/PoseStamped``
                                       ``/sofia/{robot}/pick_pregrasp``
``sofia/{robot}/flange/pose``          ``/tf`` (base -> flange)             ``tf2_msgs/msg/TFMessage``
``sofia/{robot}/calibrator/result``    ``/tf_static`` (flange -> camera)    ``tf2_msgs/msg/TFMessage``
``sofia/{robot}/gripper/state``        ``/sofia/{robot}/gripper/joint_states``  ``sensor_msgs/msg/JointState``
=====================================  ===================================  ====================================

Service ``/sofia/{robot}/detect_object`` (``sofia_msgs/srv/DetectObject``): the request's cloud
(or, when empty, the latest cloud) goes to the detector's ``detect`` queryable.

In (by configuration): a ROS 2 camera driver's cloud topic -> ``sofia/{robot}/camera/points``;
``/tf`` -> the base -> flange pose composed along the tf chain -> ``sofia/{robot}/flange/pose``.
What the bridge forwards into SofIA carries the attachment :data:`FORWARDED` and is not sent back.
"""

from __future__ import annotations

import functools
import logging
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh
from sofia_schemas.frames import BASE_FRAME, CAMERA_FRAME, FLANGE_FRAME
from sofia_schemas.keys import ENCODING_CDR_POINTCLOUD2, ENCODING_CDR_TRANSFORM, Keys
from sofia_schemas.messages import CalibrationResult, Detection, ErrorReply, GripperState, PickTarget
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.ros2.typesupport import decode, encode
from sofia_schemas.rosmsg import decode_flange_pose, encode_flange_pose

from ..client import fetch_latest
from .failures import JSON_QUERY, Request, detect_failure, json_query_failure
from .rmw import STATIC_QOS, Attachment, Graph, Node, Qos, reply, sample_attachment
from .tfchain import TfChain

log = logging.getLogger("sofia.ros2")
FORWARDED = b"sofia-ros2-forwarded"

CALIBRATOR_OPS = ("add", "remove", "reset", "solve", "save", "samples", "result")
CLOUD_QOS = Qos(depth=5, block=True)


@dataclass
class BridgeConfig:
    robot: str
    domain: int | None = None
    camera_frame: str = CAMERA_FRAME  # child frame of the calibration on /tf_static
    camera_topic: str = "/camera/camera/depth/color/points"  # ROS 2 cloud taken in ("" = none)
    tf_input: bool = True  # compose the flange pose from ROS 2 /tf
    base_frame: str = BASE_FRAME
    flange_frame: str = FLANGE_FRAME
    detect_timeout_s: float = 10.0


def _forwarded(sample: zenoh.Sample) -> bool:
    return sample.attachment is not None and sample.attachment.to_bytes() == FORWARDED


class Bridge:
    """Declares the ROS 2 graph on ``session``; :meth:`close` undeclares it."""

    def __init__(self, session: zenoh.Session, config: BridgeConfig) -> None:
        self.session, self.config = session, config
        self.keys = keys = Keys(config.robot)
        self.graph = Graph(session, config.domain)
        self.counters = {"out": 0, "in": 0, "requests": 0, "errors": 0}
        self.last_error = ""
        # (query, its attachment, request CDR, handler CDR -> CDR, error message -> response CDR)
        self.requests: queue.Queue[Request] = queue.Queue()
        ns = f"/sofia/{config.robot}"
        self.nodes: list[Node] = []
        detector, calibrator = self._node("sofia_detector"), self._node("sofia_calibrator")
        gripper, bus = self._node("sofia_gripper"), self._node("sofia_bus")
        pub = {
            "points": bus.publisher(f"{ns}/points", cv.POINTCLOUD2, CLOUD_QOS),
            "camera": bus.publisher(f"{ns}/camera/points", cv.POINTCLOUD2, CLOUD_QOS),
            "tf": bus.publisher("/tf", cv.TF_MESSAGE, Qos(depth=100)),
            "detections": detector.publisher(f"{ns}/detections", cv.DETECTIONS),
            "pick": detector.publisher(f"{ns}/pick_target", cv.POSE_STAMPED),
            "pregrasp": detector.publisher(f"{ns}/pick_pregrasp", cv.POSE_STAMPED),
            "tf_static": calibrator.publisher("/tf_static", cv.TF_MESSAGE, STATIC_QOS),
            "joints": gripper.publisher(f"{ns}/gripper/joint_states", cv.JOINT_STATE),
        }
        self.pub = pub
        self.detect_service = detector.service(
            f"{ns}/detect_object", cv.DETECT_OBJECT, self._on_request(self.detect, detect_failure)
        )
        for op in CALIBRATOR_OPS:  # sofia_msgs/srv/JsonQuery: the calibrator's queryables, JSON in and out
            key = keys.calibrator_op(op)
            calibrator.service(
                f"{ns}/calibrator/{op}", JSON_QUERY,
                self._on_request(functools.partial(self.json_query, key), json_query_failure),
            )  # fmt: skip
        self.chain = TfChain(config.base_frame, config.flange_frame)
        if config.camera_topic:
            bus.subscription(config.camera_topic, cv.POINTCLOUD2, self._on_ros_cloud, CLOUD_QOS)
        if config.tf_input:
            bus.subscription("/tf", cv.TF_MESSAGE, self._on_ros_tf, Qos(depth=100))
        self._subs = [
            session.declare_subscriber(keys.points, self._relay(pub["points"])),
            session.declare_subscriber(keys.camera_points, self._relay(pub["camera"])),
            session.declare_subscriber(keys.detections, self._convert(Detection, self._detections)),
            session.declare_subscriber(keys.pick_target, self._convert(PickTarget, self._pick)),
            session.declare_subscriber(
                keys.calibration_result, self._convert(CalibrationResult, self._calib)
            ),
            session.declare_subscriber(keys.gripper_state, self._convert(GripperState, self._joints)),
            session.declare_subscriber(keys.flange_pose, self._on_flange),
        ]
        self._stop = threading.Event()
        self._worker = threading.Thread(target=self._serve, name="ros2-detect", daemon=True)
        self._worker.start()
        # the calibrator's current result, if it has one, for late starts of the bridge
        self._fetching = fetch_latest(
            session,
            keys.calibration_result,
            self._convert(CalibrationResult, self._calib),
            self._stop,
            timeout=3.0,
        )

    def _node(self, name: str) -> Node:
        node = self.graph.node(name)
        self.nodes.append(node)
        return node

    def _error(self, message: str) -> None:
        self.counters["errors"] += 1
        self.last_error = message
        log.warning("%s", message)

    # --- SofIA -> ROS 2 ---------------------------------------------------
    def _relay(self, publisher: Any) -> Callable[[zenoh.Sample], None]:
        def relay(sample: zenoh.Sample) -> None:
            if not _forwarded(sample):
                publisher.put(sample.payload.to_bytes())
                self.counters["out"] += 1

        return relay

    def _convert(self, model: Any, then: Callable[[Any], None]) -> Callable[[zenoh.Sample], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            try:
                then(model.model_validate_json(sample.payload.to_bytes()))
                self.counters["out"] += 1
            except ValueError as e:
                self._error(f"{sample.key_expr}: {model.__name__} not converted: {e}")

        return on_sample

    def _detections(self, det: Detection) -> None:
        self.pub["detections"].put(encode(cv.detection_array(det), cv.DETECTIONS))

    def _pick(self, pick: PickTarget) -> None:
        grasp, pregrasp = cv.pick_poses(pick)
        self.pub["pick"].put(encode(grasp, cv.POSE_STAMPED))
        self.pub["pregrasp"].put(encode(pregrasp, cv.POSE_STAMPED))

    def _calib(self, result: CalibrationResult) -> None:
        tf = cv.tf_message([cv.calibration_transform(result, self.config.camera_frame)])
        self.pub["tf_static"].put(encode(tf, cv.TF_MESSAGE))
        log.info("calibration %d on /tf_static: %s -> %s", result.stamp_ns, result.parent_frame,
                 self.config.camera_frame)  # fmt: skip

    def _joints(self, state: GripperState) -> None:
        self.pub["joints"].put(encode(cv.joint_state(state), cv.JOINT_STATE))

    def _on_flange(self, sample: zenoh.Sample) -> None:
        if _forwarded(sample):
            return
        try:
            pose = decode_flange_pose(sample.payload.to_bytes())
        except ValueError as e:
            self._error(f"flange pose: {e}")
            return
        self.pub["tf"].put(encode(cv.tf_message([cv.flange_transform(pose)]), cv.TF_MESSAGE))
        self.counters["out"] += 1

    # --- ROS 2 -> SofIA ---------------------------------------------------
    def _on_ros_cloud(self, cdr: bytes, _att: Attachment | None) -> None:
        self.session.put(
            self.keys.camera_points, cdr, encoding=ENCODING_CDR_POINTCLOUD2, attachment=FORWARDED
        )
        self.counters["in"] += 1

    def _on_ros_tf(self, cdr: bytes, _att: Attachment | None) -> None:
        try:
            msg = decode(cdr, cv.TF_MESSAGE)
        except ValueError as e:
            self._error(f"/tf: {e}")
            return
        pose = self.chain.update(msg.transforms)
        if pose is not None:
            self.session.put(self.keys.flange_pose, encode_flange_pose(pose), encoding=ENCODING_CDR_TRANSFORM,
                             attachment=FORWARDED)  # fmt: skip
            self.counters["in"] += 1

    # --- detect_object ----------------------------------------------------
    def _on_request(
        self, handle: Callable[[bytes], bytes], failure: Callable[[str], bytes]
    ) -> Callable[[zenoh.Query], None]:
        """A service's queryable callback: hands the request to the worker (``handle``: CDR -> CDR;
        ``failure``: the response CDR saying what went wrong, as a ROS service answers errors:
        rmw_zenoh's client drops error replies and would wait for its query timeout)."""

        def on_query(query: zenoh.Query) -> None:
            att = sample_attachment(query)
            if att is None:  # not an rmw_zenoh client (it always sends one): a plain Zenoh error
                query.reply_err("rmw_zenoh service request without its attachment (sequence number, gid)")
                query.drop()
                return
            payload = query.payload.to_bytes() if query.payload is not None else b""
            self.requests.put((query, att, payload, handle, failure))

        return on_query

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                query, att, payload, handle, failure = self.requests.get(timeout=0.2)
            except queue.Empty:
                continue
            self.counters["requests"] += 1
            try:
                response = handle(payload)
            except Exception as e:  # still answer, in the response: a ROS client must not hang
                log.exception("service %s", query.key_expr)
                self._error(f"{query.key_expr}: {type(e).__name__}: {e}")
                response = failure(f"{type(e).__name__}: {e}")
            reply(query, att, response)

    def json_query(self, key: str, request_cdr: bytes) -> bytes:
        """A ``JsonQuery`` request forwarded to the SofIA queryable ``key``."""
        try:
            request = decode(request_cdr, f"{JSON_QUERY}_Request")
        except ValueError as e:
            return json_query_failure(f"the request is not a {JSON_QUERY} request: {e}")
        payload = request.json.encode() if request.json else None
        response = cv.new(f"{JSON_QUERY}_Response", success=False, message=f"no answer on {key}", json="")
        for r in self.session.get(key, payload=payload, timeout=self.config.detect_timeout_s):
            answer = r.ok if r.ok is not None else r.err
            if answer is None:
                continue
            ok, text = r.ok is not None, answer.payload.to_bytes().decode(errors="replace")
            try:
                message = "" if ok else ErrorReply.model_validate_json(text).message
            except ValueError:
                message = text
            response = cv.new(f"{JSON_QUERY}_Response", success=ok, message=message, json=text)
            break
        return encode(response, f"{JSON_QUERY}_Response")

    def detect(self, request_cdr: bytes) -> bytes:
        """The DetectObject response (CDR) for a request (CDR), through the detector's queryable."""
        return encode(self._detect(request_cdr), f"{cv.DETECT_OBJECT}_Response")

    def _detect(self, request_cdr: bytes) -> Any:
        try:
            request = decode(request_cdr, f"{cv.DETECT_OBJECT}_Request")
        except ValueError as e:
            return cv.detect_response(None, str(e))
        cloud = request.cloud
        payload = encode(cloud, cv.POINTCLOUD2) if cloud.width * cloud.height > 0 else None
        for r in self.session.get(self.keys.detect, payload=payload, timeout=self.config.detect_timeout_s):
            if r.ok is not None:
                return cv.detect_response(Detection.model_validate_json(r.ok.payload.to_bytes()))
            err = r.err.payload.to_bytes() if r.err is not None else b""
            try:
                return cv.detect_response(None, ErrorReply.model_validate_json(err).message)
            except ValueError:
                return cv.detect_response(None, err.decode(errors="replace"))
        return cv.detect_response(None, f"no detector answered on {self.keys.detect}")

    def close(self) -> None:
        """Undeclare everything; the threads leave the session's calls first (it cannot close while
        a thread is inside one: see :func:`..client.fetch_latest`)."""
        self._stop.set()
        self._worker.join(timeout=self.config.detect_timeout_s + 1.0)  # a request in flight ends
        self._fetching.join(timeout=5.0)
        for s in self._subs:
            s.undeclare()
        for node in self.nodes:
            node.close()
