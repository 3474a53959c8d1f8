"""SofIA calibrator: point-based hand-eye calibration (``T_flange_cam``), library and online service.

The names below are loaded on first use (PEP 562), so that commands which only register their
options (``sofia --help``, every other service's command) do not pay for SciPy's statistics and the
compiled fit: that import is about 0.55 s of CPU per ``sofia`` process.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

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

if TYPE_CHECKING:
    from .any_target import calibrate_target
    from .fitting.calibrate import Calibration, calibrate
    from .fitting.diagnostics import LAB_SPREAD_LIMIT_MM, dissipation, map_to_base, spread
    from .fitting.fit import Fit
    from .fitting.solver import Solution, solve
    from .formats import ros1_static_transform, ros2_static_transform, to_message, to_yaml
    from .inputs.lab import read_lab, read_poses, read_tfs

_LAZY = {  # name -> the submodule that defines it
    "calibrate_target": ".any_target",
    **dict.fromkeys(("Calibration", "calibrate"), ".fitting.calibrate"),
    **dict.fromkeys(("LAB_SPREAD_LIMIT_MM", "dissipation", "map_to_base", "spread"), ".fitting.diagnostics"),
    "Fit": ".fitting.fit",
    **dict.fromkeys(("Solution", "solve"), ".fitting.solver"),
    **dict.fromkeys(("ros1_static_transform", "ros2_static_transform", "to_message", "to_yaml"), ".formats"),
    **dict.fromkeys(("read_lab", "read_poses", "read_tfs"), ".inputs.lab"),
}  # fmt: skip


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value


__all__ = [
    "LAB_SPREAD_LIMIT_MM", "BlobAmbiguous", "BlobCutByEdge", "BlobNoDepth", "BlobNotFound",
    "Calibration", "CalibrationError", "DegenerateMotion", "Fit", "InputMismatch", "ParseError",
    "Solution", "TooFewSamples", "calibrate", "calibrate_target", "dissipation", "map_to_base", "read_lab", "read_poses",
    "read_tfs", "ros1_static_transform", "ros2_static_transform", "solve", "spread", "to_message",
    "to_yaml",
]  # fmt: skip
