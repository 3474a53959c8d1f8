"""SofIA camera: the RealSense D435 on the bus through librealsense, and its simulation."""

from .errors import BadOption, CameraError, CameraUnavailable, FramesStopped, UnsupportedMode
from .intrinsics import Intrinsics, StreamSpec, d435_spec
from .meta import CloudMeta
from .software import SoftwareCamera

__all__ = [
    "BadOption", "CameraError", "CameraUnavailable", "CloudMeta", "FramesStopped", "Intrinsics",
    "SoftwareCamera", "StreamSpec", "UnsupportedMode", "d435_spec",
]  # fmt: skip
