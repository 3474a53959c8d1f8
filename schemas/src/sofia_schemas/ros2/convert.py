"""SofIA bus messages <-> standard ROS 2 messages (``rosbags`` objects, CDR via typesupport).

- :class:`~sofia_schemas.Detection` -> ``vision_msgs/msg/Detection3DArray``: one ``Detection3D``
  per object, bbox centre pose (yaw about z) and size (extents), one hypothesis whose class id is
  ``"<row>,<col>/red"`` or ``"<row>,<col>/not_red"`` (``"off_board/..."`` off the grid) and whose
  score is the detector's confidence;
- :class:`~sofia_schemas.PickTarget` -> two ``geometry_msgs/msg/PoseStamped`` (grasp, pre-grasp);
- a calibration result or a flange pose -> ``geometry_msgs/msg/TransformStamped`` (in a
  ``tf2_msgs/msg/TFMessage``);
- :class:`~sofia_schemas.GripperState` -> ``sensor_msgs/msg/JointState`` (opening in metres);
- a Detection -> the ``sofia_msgs/srv/DetectObject`` response.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..frames import BASE_FRAME
from ..messages import CalibrationResult, DetectedObject, Detection, FlangePose, GripperState, PickTarget
from .typesupport import new

DETECTIONS = "vision_msgs/msg/Detection3DArray"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
JOINT_STATE = "sensor_msgs/msg/JointState"
POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
DETECT_OBJECT = "sofia_msgs/srv/DetectObject"
GRIPPER_JOINT = "sofia_finger_opening"
Vec = Sequence[float] | np.ndarray  # 3 (or 4 for quaternions x y z w) floats


def stamp(stamp_ns: int) -> Any:
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return new("builtin_interfaces/msg/Time", sec=sec, nanosec=nanosec)


def stamp_ns(msg_stamp: Any) -> int:
    return int(msg_stamp.sec) * 1_000_000_000 + int(msg_stamp.nanosec)


def header(ns: int, frame_id: str) -> Any:
    return new("std_msgs/msg/Header", stamp=stamp(ns), frame_id=frame_id)


def point(p: Vec) -> Any:
    return new("geometry_msgs/msg/Point", x=float(p[0]), y=float(p[1]), z=float(p[2]))


def vector(v: Vec) -> Any:
    return new("geometry_msgs/msg/Vector3", x=float(v[0]), y=float(v[1]), z=float(v[2]))


def quaternion(q_xyzw: Vec) -> Any:
    return new("geometry_msgs/msg/Quaternion", x=float(q_xyzw[0]), y=float(q_xyzw[1]),
               z=float(q_xyzw[2]), w=float(q_xyzw[3]))  # fmt: skip


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """Rotation about z by ``yaw`` radians, x y z w."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def pose(position: Vec, q_xyzw: Vec) -> Any:
    return new("geometry_msgs/msg/Pose", position=point(position), orientation=quaternion(q_xyzw))


def class_id(obj: DetectedObject) -> str:
    colour = "red" if obj.allowed else "not_red"
    where = f"{obj.field[0]},{obj.field[1]}" if obj.field is not None else "off_board"
    return f"{where}/{colour}"


def detection_array(det: Detection) -> Any:
    """``vision_msgs/msg/Detection3DArray`` of a detection (frame: ``det.frame_id``)."""
    head = header(det.stamp_ns, det.frame_id)
    items = []
    for i, obj in enumerate(det.objects):
        centre = pose(obj.center, yaw_quaternion(obj.yaw))
        hypothesis = new(
            "vision_msgs/msg/ObjectHypothesisWithPose",
            hypothesis=new(
                "vision_msgs/msg/ObjectHypothesis", class_id=class_id(obj), score=float(obj.confidence)
            ),
            pose=new("geometry_msgs/msg/PoseWithCovariance", pose=centre, covariance=np.zeros(36)),
        )
        bbox = new("vision_msgs/msg/BoundingBox3D", center=centre, size=vector(obj.extents))
        items.append(
            new("vision_msgs/msg/Detection3D", header=head, results=[hypothesis], bbox=bbox, id=str(i))
        )
    return new(DETECTIONS, header=head, detections=items)


def new_pose_stamped(ns: int, frame_id: str, position: Vec, q_xyzw: Vec) -> Any:
    """``geometry_msgs/msg/PoseStamped``."""
    return new(POSE_STAMPED, header=header(ns, frame_id), pose=pose(position, q_xyzw))


def pick_poses(pick: PickTarget) -> tuple[Any, Any]:
    """(grasp, pre-grasp) ``geometry_msgs/msg/PoseStamped`` of the flange, base frame."""
    grasp = new_pose_stamped(pick.stamp_ns, pick.frame_id, pick.grasp_translation, pick.rotation_xyzw)
    pregrasp = new_pose_stamped(pick.stamp_ns, pick.frame_id, pick.pregrasp_translation, pick.rotation_xyzw)
    return grasp, pregrasp


def transform_stamped(ns: int, parent: str, child: str, translation: Vec, q_xyzw: Vec) -> Any:
    """``geometry_msgs/msg/TransformStamped``: the pose of ``child`` in ``parent``."""
    tf = new("geometry_msgs/msg/Transform", translation=vector(translation), rotation=quaternion(q_xyzw))
    return new(TRANSFORM_STAMPED, header=header(ns, parent), child_frame_id=child, transform=tf)


def tf_message(transforms: list[Any]) -> Any:
    return new(TF_MESSAGE, transforms=transforms)


def calibration_transform(result: CalibrationResult, camera_frame: str) -> Any:
    """``T_flange_cam`` as a static transform ``result.parent_frame`` -> ``camera_frame``."""
    return transform_stamped(result.stamp_ns, result.parent_frame, camera_frame, result.translation,
                             result.quaternion_xyzw)  # fmt: skip


def flange_transform(pose_: FlangePose) -> Any:
    return transform_stamped(pose_.stamp_ns, pose_.frame_id, pose_.child_frame_id, pose_.translation,
                             pose_.rotation_xyzw)  # fmt: skip


def flange_pose(msg: Any) -> FlangePose:
    """A :class:`FlangePose` from a ``TransformStamped`` object."""
    tr, rot = msg.transform.translation, msg.transform.rotation
    return FlangePose(stamp_ns=stamp_ns(msg.header.stamp), frame_id=msg.header.frame_id,
                      child_frame_id=msg.child_frame_id, translation=(tr.x, tr.y, tr.z),
                      rotation_xyzw=(rot.x, rot.y, rot.z, rot.w))  # fmt: skip


def joint_state(state: GripperState) -> Any:
    """The finger opening (metres), velocity (rad/s) and force (N) as one joint."""

    def arr(v: float | None) -> Any:
        return np.array([math.nan if v is None else float(v)])

    opening_m = None if state.opening_mm is None else state.opening_mm / 1000.0
    return new(JOINT_STATE, header=header(state.stamp_ns, "sofia_gripper"), name=[GRIPPER_JOINT],
               position=arr(opening_m), velocity=arr(state.velocity_rad_s), effort=arr(state.force_n))  # fmt: skip


def detect_response(det: Detection | None, error: str = "", frame_id: str = BASE_FRAME) -> Any:
    """``sofia_msgs/srv/DetectObject_Response`` of a detection (or of an error message)."""
    zero = (0.0, 0.0, 0.0)
    if det is None:
        return new(f"{DETECT_OBJECT}_Response", success=False, status="error", message=error,
                   header=header(0, frame_id), centroid=point(zero), center=point(zero), objects=[])  # fmt: skip
    allowed = [o for o in det.objects if o.allowed]
    first = allowed[0] if allowed else None
    objects = [
        new(
            "sofia_msgs/msg/DetectedObject",
            center=point(o.center),
            centroid=point(o.centroid),
            extents=vector(o.extents),
            yaw=float(o.yaw),
            row=o.field[0] if o.field else -1,
            col=o.field[1] if o.field else -1,
            allowed=bool(o.allowed),
            n_points=int(o.n_points),
            confidence=float(o.confidence),
        )
        for o in det.objects
    ]
    message = det.detail or ("" if first else "no object on an allowed (red) field")
    return new(
        f"{DETECT_OBJECT}_Response", success=first is not None, status=det.status, message=message,
        header=header(det.stamp_ns, det.frame_id), centroid=point(first.centroid if first else zero),
        center=point(first.center if first else zero), objects=objects,
    )  # fmt: skip
