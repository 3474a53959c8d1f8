"""SofIA arm: the Franka robot through franky, flange pose and joint states on the bus, safe motion.

``ArmConfig`` and ``load_config`` are loaded on first use (PEP 562): the configuration pulls in the
kinematics and SciPy's rotations (about 0.2 s of CPU), which commands that only register their
options do not need.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

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

if TYPE_CHECKING:
    from .config import ArmConfig, load_config


def __getattr__(name: str) -> Any:
    if name not in ("ArmConfig", "load_config"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from . import config

    return getattr(config, name)


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
