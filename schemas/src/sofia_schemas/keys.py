"""Every Zenoh key expression of the SofIA bus, in one place.

All keys are namespaced by a robot id (default ``panda``): ``sofia/{robot}/...``.
Services build their keys with :class:`Keys` so that a change of layout is made here only.

Payloads (see README, "Key expressions"):

=================================  ==============================================  =========
key                                payload                                         kind
=================================  ==============================================  =========
sofia/{robot}/points               CDR sensor_msgs/msg/PointCloud2, base frame     put
sofia/{robot}/camera/points        CDR sensor_msgs/msg/PointCloud2, camera frame   put
sofia/{robot}/camera/camera_info   CDR sensor_msgs/msg/CameraInfo (colour stream)  put
sofia/{robot}/flange/pose          CDR geometry_msgs/msg/TransformStamped or       put
                                   JSON FlangePose (base -> flange)
sofia/{robot}/detector/detections  JSON Detection                                  put
sofia/{robot}/detector/detect      query: CDR PointCloud2 or empty -> Detection    queryable
sofia/{robot}/detector/status      query -> JSON ServiceStatus                     queryable
sofia/{robot}/calibrator/blob      CDR geometry_msgs/msg/PointStamped or JSON      put
                                   BlobObservation (camera frame)
sofia/{robot}/calibrator/result    JSON CalibrationResult                          put + queryable
sofia/{robot}/calibrator/<op>      queryables: add, remove, reset, solve, save     queryable
sofia/{robot}/gripper/state        JSON GripperState                               put
sofia/{robot}/gripper/command      query: JSON GripperCommand -> GripperResult     queryable
sofia/{robot}/arm/command          query: JSON ArmCommand -> ArmResult             queryable
sofia/{robot}/arm/state            JSON ArmState                                   put
sofia/{robot}/arm/joint_states     CDR sensor_msgs/msg/JointState                  put
sofia/{robot}/arm/progress         JSON ArmPhase (calibration, pick and place)     put
sofia/{robot}/pick/target          JSON PickTarget                                 put
sofia/{robot}/<service>/status     JSON ServiceStatus                              put + queryable
sofia/{robot}/replay/status        JSON ServiceStatus                              put
=================================  ==============================================  =========
"""

from __future__ import annotations

import argparse
import os
import re
from dataclasses import dataclass
from typing import overload

DEFAULT_ROBOT = "panda"
ROBOT_ENV = "SOFIA_ROBOT"
ROOT = "sofia"

_ROBOT_RE = re.compile(r"[A-Za-z0-9_\-]+")

# MCAP topic names (ROS 2 style) <-> bus keys. The lab's base-frame cloud topic is /pc_glob.
TOPIC_POINTS = "/pc_glob"
TOPIC_CAMERA_POINTS = "/camera/depth/color/points"
TOPIC_CAMERA_INFO = "/camera/color/camera_info"
TOPIC_FLANGE_POSE = "/sofia/flange_pose"
TOPIC_BLOB = "/sofia/blob"

# Zenoh encodings used on the bus.
ENCODING_CDR_POINTCLOUD2 = "application/cdr;sensor_msgs/msg/PointCloud2"
ENCODING_CDR_TRANSFORM = "application/cdr;geometry_msgs/msg/TransformStamped"
ENCODING_CDR_POINT = "application/cdr;geometry_msgs/msg/PointStamped"
ENCODING_CDR_CAMERA_INFO = "application/cdr;sensor_msgs/msg/CameraInfo"
ENCODING_CDR_JOINT_STATE = "application/cdr;sensor_msgs/msg/JointState"
ENCODING_JSON = "application/json"


def default_robot() -> str:
    """The robot id from ``$SOFIA_ROBOT``, else ``panda``."""
    return os.environ.get(ROBOT_ENV, DEFAULT_ROBOT)


def add_robot_arg(parser: argparse.ArgumentParser) -> None:
    """``--robot ID`` (None when not given: the caller falls back to :func:`default_robot`)."""
    parser.add_argument("--robot", default=None, help=f"robot id (default ${ROBOT_ENV} or {DEFAULT_ROBOT})")


# The key ``{prefix}/{path}`` of a :class:`Keys`, read as an attribute: a property (without a class
# docstring), so that the reference pages list it with its own docstring.
class _Key(property):
    def __init__(self, path: str, doc: str | None = None) -> None:
        super().__init__(lambda keys: f"{keys.prefix}/{path}")
        self.__doc__ = doc

    @overload
    def __get__(self, keys: None, owner: type, /) -> _Key: ...
    @overload
    def __get__(self, keys: Keys, owner: type | None = None, /) -> str: ...
    def __get__(self, keys: Keys | None, owner: type | None = None, /) -> str | _Key:
        return self if keys is None else str(self.fget(keys))  # type: ignore[misc]


@dataclass(frozen=True)
class Keys:
    """Key expressions for one robot id.

    >>> Keys("panda").points
    'sofia/panda/points'
    """

    robot: str = DEFAULT_ROBOT

    def __post_init__(self) -> None:
        if not _ROBOT_RE.fullmatch(self.robot):
            raise ValueError(
                f"robot id {self.robot!r} is not a valid key chunk: use letters, digits, '_' and '-'"
            )

    @property
    def prefix(self) -> str:
        return f"{ROOT}/{self.robot}"

    # --- data plane -------------------------------------------------------
    points = _Key("points", "Point clouds in the robot base frame (the lab's ``/pc_glob``).")
    camera_points = _Key("camera/points", "Point clouds in the camera optical frame.")
    camera_info = _Key("camera/camera_info", "CameraInfo of the colour stream the camera clouds are in.")
    flange_pose = _Key("flange/pose", "Stamped base -> flange poses.")
    # --- detector ---------------------------------------------------------
    detections = _Key("detector/detections")
    detect = _Key("detector/detect")
    # --- calibrator -------------------------------------------------------
    calibrator = _Key("calibrator")
    blob = _Key("calibrator/blob", "Blob observations in the camera optical frame.")
    calibration_result = _Key("calibrator/result")

    def calibrator_op(self, op: str) -> str:
        """Calibrator queryables: ``add``, ``remove``, ``reset``, ``solve``, ``save``, ``samples``."""
        return f"{self.calibrator}/{op}"

    # --- gripper ----------------------------------------------------------
    gripper_state = _Key("gripper/state")
    gripper_command = _Key("gripper/command")
    # --- arm --------------------------------------------------------------
    arm_command = _Key("arm/command", "Arm commands: query JSON ArmCommand -> JSON ArmResult.")
    arm_state = _Key("arm/state", "JSON ArmState (mode, errors, moving, last command).")
    arm_joint_states = _Key(
        "arm/joint_states", "Measured joint positions and velocities (CDR sensor_msgs/msg/JointState)."
    )
    arm_progress = _Key(
        "arm/progress", "Steps of a running compound command (JSON ArmPhase per pose or phase)."
    )
    # --- system -----------------------------------------------------------
    pick_target = _Key("pick/target")

    def status(self, service: str) -> str:
        """Status of a service (``detector``, ``calibrator``, ``gripper``, ``replay``)."""
        return f"{self.prefix}/{service}/status"

    all = _Key("**")

    def topic_map(self) -> dict[str, str]:
        """Default MCAP topic -> key mapping used by the replayer."""
        return {
            TOPIC_POINTS: self.points,
            TOPIC_CAMERA_POINTS: self.camera_points,
            TOPIC_CAMERA_INFO: self.camera_info,
            TOPIC_FLANGE_POSE: self.flange_pose,
            TOPIC_BLOB: self.blob,
        }
