"""Pydantic models of every JSON message on the SofIA bus."""

from .base import SCHEMA_VERSION, ErrorReply, Message, ServiceStatus, now_ns
from .calibration import CalibrationResult, CalibrationSample
from .detection import DetectedObject, Detection
from .geometry import BlobObservation, FlangePose, PointCloudInfo
from .gripper import GripperAction, GripperCommand, GripperResult, GripperState
from .pick import PickTarget

ALL_MESSAGES: tuple[type[Message], ...] = (
    PointCloudInfo, FlangePose, BlobObservation, Detection, DetectedObject, CalibrationSample,
    CalibrationResult, GripperCommand, GripperResult, GripperState, PickTarget, ErrorReply,
    ServiceStatus,
)  # fmt: skip

__all__ = [
    "ALL_MESSAGES", "SCHEMA_VERSION", "BlobObservation", "CalibrationResult", "CalibrationSample",
    "DetectedObject", "Detection", "ErrorReply", "FlangePose", "GripperAction", "GripperCommand",
    "GripperResult", "GripperState", "Message", "PickTarget", "PointCloudInfo", "ServiceStatus",
    "now_ns",
]  # fmt: skip
