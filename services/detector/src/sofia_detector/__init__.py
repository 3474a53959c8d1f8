"""SofIA detector: the object on the board, as a library (``detect``) and a Zenoh service."""

from .detect import as_cloud, detect
from .errors import (
    BadCloud,
    DetectorError,
    TransformUnavailable,
    UnreadableFile,
    WrongCloud,
)
from .params import DetectorParams

__all__ = [
    "BadCloud", "DetectorError", "DetectorParams", "TransformUnavailable",
    "UnreadableFile", "WrongCloud", "as_cloud", "detect",
]  # fmt: skip
