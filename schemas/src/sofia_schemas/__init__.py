"""SofIA data plane: bus messages, key expressions, the board, PointCloud2 CDR, Zenoh config.

Frame math lives in :mod:`sofia_schemas.transforms` (needs the ``ros`` extra's scipy); it is not
imported here, so the gripper installs without scipy.
"""

from . import keys, pointcloud
from .board import Board
from .errors import (
    MissingField,
    PayloadError,
    PointCloudError,
    SizeMismatch,
    SofiaError,
    TruncatedMessage,
    UnsupportedEncoding,
)
from .keys import DEFAULT_ROBOT, Keys
from .messages import (
    ALL_MESSAGES,
    SCHEMA_VERSION,
    BlobObservation,
    CalibrationResult,
    CalibrationSample,
    DetectedObject,
    Detection,
    ErrorReply,
    FlangePose,
    GripperCommand,
    GripperResult,
    GripperState,
    Message,
    PickTarget,
    PointCloudInfo,
    ServiceStatus,
    now_ns,
)
from .pointcloud import PointCloud2, PointField
from .zenoh_config import ZenohOptions, add_zenoh_args, open_session, zenoh_config

__all__ = [
    "ALL_MESSAGES", "DEFAULT_ROBOT", "SCHEMA_VERSION", "BlobObservation", "Board",
    "CalibrationResult", "CalibrationSample", "DetectedObject", "Detection", "ErrorReply",
    "FlangePose", "GripperCommand", "GripperResult", "GripperState", "Keys", "Message",
    "MissingField", "PayloadError", "PickTarget", "PointCloud2", "PointCloudError",
    "PointCloudInfo", "PointField", "ServiceStatus", "SizeMismatch", "SofiaError",
    "TruncatedMessage", "UnsupportedEncoding", "ZenohOptions", "add_zenoh_args", "keys",
    "now_ns", "open_session", "pointcloud", "zenoh_config",
]  # fmt: skip
