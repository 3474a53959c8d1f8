"""SofIA data plane, what travels on the bus: messages, key expressions, the board, PointCloud2 CDR.

The Zenoh session, the status endpoint and the query client are in :mod:`sofia_runtime`.

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

__all__ = [
    "ALL_MESSAGES", "DEFAULT_ROBOT", "SCHEMA_VERSION", "BlobObservation", "Board",
    "CalibrationResult", "CalibrationSample", "DetectedObject", "Detection", "ErrorReply",
    "FlangePose", "GripperCommand", "GripperResult", "GripperState", "Keys", "Message",
    "MissingField", "PayloadError", "PickTarget", "PointCloud2", "PointCloudError",
    "PointCloudInfo", "PointField", "ServiceStatus", "SizeMismatch", "SofiaError",
    "TruncatedMessage", "UnsupportedEncoding", "keys", "now_ns", "pointcloud",
]  # fmt: skip
