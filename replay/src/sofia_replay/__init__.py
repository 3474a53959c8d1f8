"""SofIA recordings: MCAP I/O, ROS 1 bag conversion, the replayer (and synthetic scenes in ``synth``)."""

from .errors import (
    BadMappingError,
    BadTruthError,
    NotAnMcapError,
    RecordingError,
    RecordingNotFoundError,
    UnknownSchemaError,
)
from .mcap_io import (
    McapWriter,
    RecordedMessage,
    RecordingSummary,
    iter_blobs,
    iter_clouds,
    iter_flange_poses,
    iter_messages,
    read_metadata,
    read_truth,
    summary,
)

__all__ = [
    "BadMappingError", "BadTruthError", "McapWriter", "NotAnMcapError", "RecordedMessage",
    "RecordingError",
    "RecordingNotFoundError", "RecordingSummary", "UnknownSchemaError", "iter_blobs", "iter_clouds",
    "iter_flange_poses", "iter_messages", "read_metadata", "read_truth", "summary",
]  # fmt: skip
