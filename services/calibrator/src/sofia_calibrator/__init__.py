"""SofIA calibrator: point-based hand-eye calibration (``T_flange_cam``), library and online service."""

from .any_target import calibrate_target
from .errors import (
    BlobAmbiguous,
    BlobCutByEdge,
    BlobNoDepth,
    BlobNotFound,
    CalibrationError,
    DegenerateMotion,
    InputMismatch,
    ParseError,
    TooFewSamples,
)
from .fitting.calibrate import Calibration, calibrate
from .fitting.diagnostics import LAB_SPREAD_LIMIT_MM, dissipation, map_to_base, spread
from .fitting.fit import Fit
from .fitting.solver import Solution, solve
from .formats import ros1_static_transform, ros2_static_transform, to_message, to_yaml
from .inputs.lab import read_lab, read_poses, read_tfs

__all__ = [
    "LAB_SPREAD_LIMIT_MM", "BlobAmbiguous", "BlobCutByEdge", "BlobNoDepth", "BlobNotFound",
    "Calibration", "CalibrationError", "DegenerateMotion", "Fit", "InputMismatch", "ParseError",
    "Solution", "TooFewSamples", "calibrate", "calibrate_target", "dissipation", "map_to_base", "read_lab", "read_poses",
    "read_tfs", "ros1_static_transform", "ros2_static_transform", "solve", "spread", "to_message",
    "to_yaml",
]  # fmt: skip
