"""SofIA arm: the Franka robot through franky, flange pose and joint states on the bus, safe motion."""

from .config import ArmConfig, load_config
from .errors import (
    ArmError,
    BelowSurface,
    NotReady,
    OutsideJointLimits,
    OutsideWorkspace,
    TargetRefused,
    Unavailable,
    Unreachable,
)
from .motion import ArmMotion

__all__ = [
    "ArmConfig",
    "ArmError",
    "ArmMotion",
    "BelowSurface",
    "NotReady",
    "OutsideJointLimits",
    "OutsideWorkspace",
    "TargetRefused",
    "Unavailable",
    "Unreachable",
    "load_config",
]  # fmt: skip
