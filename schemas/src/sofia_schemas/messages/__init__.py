"""Pydantic models of every JSON message on the SofIA bus."""

from .arm import ArmCommand, ArmCommandName, ArmMode, ArmPhase, ArmResult, ArmState, ArmStatus
from .base import SCHEMA_VERSION, ErrorReply, Message, ServiceStatus, now_ns
from .calibration import (
    CalibrationFiles,
    CalibrationRemove,
    CalibrationResult,
    CalibrationSample,
    CalibrationSamples,
    CalibrationSolveOptions,
    CalibrationSummary,
)
from .detection import DetectedObject, Detection
from .geometry import BlobObservation, FlangePose, PointCloudInfo
from .gripper import GripperAction, GripperCommand, GripperResult, GripperState
from .pick import PickTarget

ALL_MESSAGES: tuple[type[Message], ...] = (
    PointCloudInfo, FlangePose, BlobObservation, Detection, DetectedObject, CalibrationSample,
    CalibrationResult, CalibrationSummary, CalibrationSamples, CalibrationSolveOptions,
    CalibrationRemove, CalibrationFiles, GripperCommand, GripperResult, GripperState, PickTarget, ErrorReply,
    ServiceStatus, ArmCommand, ArmResult, ArmPhase, ArmState,
)  # fmt: skip

__all__ = [
    "ALL_MESSAGES",
    "SCHEMA_VERSION",
    "ArmCommand",
    "ArmCommandName",
    "ArmMode",
    "ArmPhase",
    "ArmResult",
    "ArmState",
    "ArmStatus",
    "BlobObservation",
    "CalibrationFiles",
    "CalibrationRemove",
    "CalibrationResult",
    "CalibrationSample",
    "CalibrationSamples",
    "CalibrationSolveOptions",
    "CalibrationSummary",
    "DetectedObject",
    "Detection",
    "ErrorReply",
    "FlangePose",
    "GripperAction",
    "GripperCommand",
    "GripperResult",
    "GripperState",
    "Message",
    "PickTarget",
    "PointCloudInfo",
    "ServiceStatus",
    "now_ns",
]  # fmt: skip
