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
    @property
    def points(self) -> str:
        """Point clouds in the robot base frame (the lab's ``/pc_glob``)."""
        return f"{self.prefix}/points"

    @property
    def camera_points(self) -> str:
        """Point clouds in the camera optical frame."""
        return f"{self.prefix}/camera/points"

    @property
    def camera_info(self) -> str:
        """CameraInfo of the colour stream the camera clouds are in."""
        return f"{self.prefix}/camera/camera_info"

    @property
    def flange_pose(self) -> str:
        """Stamped base -> flange poses."""
        return f"{self.prefix}/flange/pose"

    # --- detector ---------------------------------------------------------
    @property
    def detections(self) -> str:
        return f"{self.prefix}/detector/detections"

    @property
    def detect(self) -> str:
        return f"{self.prefix}/detector/detect"

    # --- calibrator -------------------------------------------------------
    @property
    def calibrator(self) -> str:
        return f"{self.prefix}/calibrator"

    @property
    def blob(self) -> str:
        """Blob observations in the camera optical frame."""
        return f"{self.calibrator}/blob"

    @property
    def calibration_result(self) -> str:
        return f"{self.calibrator}/result"

    def calibrator_op(self, op: str) -> str:
        """Calibrator queryables: ``add``, ``remove``, ``reset``, ``solve``, ``save``, ``samples``."""
        return f"{self.calibrator}/{op}"

    # --- gripper ----------------------------------------------------------
    @property
    def gripper_state(self) -> str:
        return f"{self.prefix}/gripper/state"

    @property
    def gripper_command(self) -> str:
        return f"{self.prefix}/gripper/command"

    # --- arm --------------------------------------------------------------
    @property
    def arm_command(self) -> str:
        """Arm commands: query JSON ArmCommand -> JSON ArmResult."""
        return f"{self.prefix}/arm/command"

    @property
    def arm_state(self) -> str:
        """JSON ArmState (mode, errors, moving, last command)."""
        return f"{self.prefix}/arm/state"

    @property
    def arm_joint_states(self) -> str:
        """Measured joint positions and velocities (CDR sensor_msgs/msg/JointState)."""
        return f"{self.prefix}/arm/joint_states"

    @property
    def arm_progress(self) -> str:
        """Steps of a running compound command (JSON ArmPhase per pose or phase)."""
        return f"{self.prefix}/arm/progress"

    # --- system -----------------------------------------------------------
    @property
    def pick_target(self) -> str:
        return f"{self.prefix}/pick/target"

    def status(self, service: str) -> str:
        """Status of a service (``detector``, ``calibrator``, ``gripper``, ``replay``)."""
        return f"{self.prefix}/{service}/status"

    @property
    def all(self) -> str:
        return f"{self.prefix}/**"

    def topic_map(self) -> dict[str, str]:
        """Default MCAP topic -> key mapping used by the replayer."""
        return {
            TOPIC_POINTS: self.points,
            TOPIC_CAMERA_POINTS: self.camera_points,
            TOPIC_CAMERA_INFO: self.camera_info,
            TOPIC_FLANGE_POSE: self.flange_pose,
            TOPIC_BLOB: self.blob,
        }
