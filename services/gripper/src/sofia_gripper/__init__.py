"""SofIA gripper: Dynamixel MX-64 driver, emulator and Zenoh service."""

from .commands import Gripper
from .config import GripperConfig, load_config, save_config
from .emulator import Emulator
from .errors import CommandError, ConfigError, GripperError, NotReady, OutOfRange

__all__ = [
    "CommandError", "ConfigError", "Emulator", "Gripper", "GripperConfig", "GripperError", "NotReady",
    "OutOfRange", "load_config", "save_config",
]  # fmt: skip
