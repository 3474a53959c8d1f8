"""A ROS 2 peer built on zenoh-ros2-sdk (an rmw_zenoh implementation independent of SofIA's),
run as its own process. It is given the message definitions locally (SofIA's shipped .msg/.srv
files) and talks to SofIA only through the Zenoh router, as a node with rmw_zenoh would.

Prints one JSON object per line:
- ``{"graph": {"topics": {name: [types]}, "services": {...}}}`` once SofIA's detections topic and detect_object service
  are discovered (``ros2 topic list`` / ``ros2 service list`` the rmw_zenoh way);
- ``{"ready": true}`` when subscribed to ``/sofia/<robot>/detections``;
- ``{"detections": ...}`` for every Detection3DArray received, decoded;
- ``{"response": ...}`` for the detect_object call (``--cloud FILE``: a CDR PointCloud2);
- ``{"calibrator": ...}`` for a call of ``/sofia/<robot>/calibrator/<op>`` (``--calibrator OP``);
- ``{"published": ...}`` once streaming ``--camera-cloud FILE`` on the camera driver's topic (2 Hz) with
  ``--tf FILE`` (JSON list of [parent, child, stamp_ns, translation, quaternion_xyzw]) on /tf.

Runs until its standard input closes.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import threading
import time
from typing import Any

import zenoh
from zenoh_ros2_sdk import (
    ROS2Publisher,
    ROS2ServiceClient,
    ROS2Subscriber,
    ZenohSession,
    get_registry,
    get_service_names_and_types,
    get_topic_names_and_types,
)

DETECTIONS = "vision_msgs/msg/Detection3DArray"
CAMERA_TOPIC = "/camera/camera/depth/color/points"


def out(obj: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


def stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def on_detections(msg: Any) -> None:
    items = []
    for d in msg.detections:
        c = d.bbox.center.position
        items.append({
            "class_id": d.results[0].hypothesis.class_id, "score": d.results[0].hypothesis.score,
            "center": [c.x, c.y, c.z], "size": [d.bbox.size.x, d.bbox.size.y, d.bbox.size.z],
        })  # fmt: skip
    out(
        {
            "detections": {
                "stamp_ns": stamp_ns(msg.header.stamp),
                "frame_id": msg.header.frame_id,
                "items": items,
            }
        }
    )


def discover(port: int, robot: str, timeout: float = 30.0) -> None:
    want_topic, want_service = f"/sofia/{robot}/detections", f"/sofia/{robot}/detect_object"
    deadline = time.monotonic() + timeout
    while True:
        topics = get_topic_names_and_types(router_port=port, timeout=1.0)
        services = get_service_names_and_types(router_port=port, timeout=1.0)
        names = {t for t, _ in topics}
        if (want_topic in names and want_service in {s for s, _ in services}) or time.monotonic() > deadline:
            out({"graph": {"topics": dict(topics), "services": dict(services)}})
            return
        time.sleep(0.3)


def fields(msg: Any) -> dict[str, Any]:
    return {f: getattr(msg, f) for f in msg.__dataclass_fields__}


def call_detect(port: int, robot: str, cloud_file: str) -> None:
    store = ZenohSession.get_instance("127.0.0.1", port).store
    client = ROS2ServiceClient(f"/sofia/{robot}/detect_object", "sofia_msgs/srv/DetectObject",
                               router_port=port, timeout=20.0)  # fmt: skip
    ZenohSession.get_instance().register_message_type(None, "sensor_msgs/msg/PointCloud2")
    cloud = store.deserialize_cdr(open(cloud_file, "rb").read(), "sensor_msgs/msg/PointCloud2")
    response = None
    for _ in range(5):  # the first query may leave before the route to the service is known
        response = client.call(cloud=cloud)
        if response is not None:
            break
        time.sleep(0.5)
    if response is None:
        out({"response": None})
        return
    c, m = response.centroid, response.center
    out({"response": {
        "success": response.success, "status": response.status, "message": response.message,
        "frame_id": response.header.frame_id, "stamp_ns": stamp_ns(response.header.stamp),
        "centroid": [c.x, c.y, c.z], "center": [m.x, m.y, m.z],
        "objects": [{"row": o.row, "col": o.col, "allowed": o.allowed,
                     "center": [o.center.x, o.center.y, o.center.z]} for o in response.objects],
    }})  # fmt: skip


def call_calibrator(port: int, robot: str, op: str) -> None:
    client = ROS2ServiceClient(f"/sofia/{robot}/calibrator/{op}", "sofia_msgs/srv/JsonQuery",
                               router_port=port, timeout=20.0)  # fmt: skip
    response = None
    for _ in range(5):
        response = client.call(json="")
        if response is not None:
            break
        time.sleep(0.5)
    out({"calibrator": None if response is None else
         {"success": response.success, "message": response.message, "json": response.json}})  # fmt: skip


def publish_camera(port: int, cloud_file: str, tf_file: str) -> None:
    store = ZenohSession.get_instance("127.0.0.1", port).store
    tf_pub = ROS2Publisher(
        "/tf", "tf2_msgs/msg/TFMessage", router_port=port, node_name="robot_state_publisher"
    )
    cloud_pub = ROS2Publisher(
        CAMERA_TOPIC, "sensor_msgs/msg/PointCloud2", router_port=port, node_name="camera"
    )
    # The SDK means reliable publishers to block under congestion (as rmw_zenoh's do) but looks for
    # zenoh.qos.CongestionControl, which zenoh-python 1.x does not have: it falls back to dropping,
    # and a 5 MB cloud is then dropped on a busy machine. Give it the blocking publisher it intends.
    session = ZenohSession.get_instance().session
    cloud_pub.pub = session.declare_publisher(
        cloud_pub.keyexpr, congestion_control=zenoh.CongestionControl.BLOCK
    )
    T = store.types
    transforms = []
    for parent, child, ns, t, q in json.load(open(tf_file)):
        transforms.append(T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
                                            frame_id=parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](*t), rotation=T["geometry_msgs/msg/Quaternion"](*q)),
        ))  # fmt: skip
    cloud = store.deserialize_cdr(open(cloud_file, "rb").read(), "sensor_msgs/msg/PointCloud2")

    def stream() -> None:  # a robot state publisher streams /tf, a camera driver its clouds
        for i in itertools.count():
            tf_pub.publish(transforms=transforms)
            if i % 10 == 9:  # 2 Hz: the stream outlives the routes' set-up on a busy machine
                cloud_pub.publish(**fields(cloud))
            time.sleep(0.05)

    threading.Thread(target=stream, daemon=True).start()
    time.sleep(1.0)
    out({"published": {"cloud_stamp_ns": stamp_ns(cloud.header.stamp), "frame_id": cloud.header.frame_id}})


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--robot", required=True)
    p.add_argument("--msgs", required=True, help="directory of .msg/.srv definitions")
    p.add_argument("--cloud", help="CDR PointCloud2 to send to detect_object")
    p.add_argument("--calibrator", help="calibrator operation to call (e.g. result)")
    p.add_argument("--camera-cloud", help="CDR PointCloud2 to publish as a ROS 2 camera driver")
    p.add_argument("--tf", help="JSON transforms to publish on /tf")
    args = p.parse_args()
    get_registry(args.msgs)  # message definitions given locally: nothing is downloaded
    ZenohSession.get_instance("127.0.0.1", args.port)
    discover(args.port, args.robot)
    sub = ROS2Subscriber(f"/sofia/{args.robot}/detections", DETECTIONS, on_detections, router_port=args.port)
    time.sleep(0.5)
    out({"ready": True})
    if args.cloud:
        call_detect(args.port, args.robot, args.cloud)
    if args.calibrator:
        call_calibrator(args.port, args.robot, args.calibrator)
    if args.camera_cloud and args.tf:
        publish_camera(args.port, args.camera_cloud, args.tf)
    sys.stdin.read()  # until the test closes our stdin
    sub.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
