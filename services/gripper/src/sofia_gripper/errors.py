"""Errors of the gripper package; each message says what was wrong and with which value."""

from __future__ import annotations

from sofia_schemas.errors import SofiaError


class GripperError(SofiaError):
    """Base class of gripper errors."""


class ConfigError(GripperError, ValueError):
    """The gripper configuration is missing or invalid."""


class BusError(GripperError):
    """The serial line or a packet exchange failed."""


class LineLost(BusError):  # noqa: N818
    def __init__(self, port: str, cause: object) -> None:
        super().__init__(f"serial line {port!r} lost: {cause}")


class CommFailed(BusError):  # noqa: N818
    def __init__(self, what: str, result: str) -> None:
        super().__init__(f"{what}: {result}")


class ServoRefused(GripperError):  # noqa: N818
    """The servo answered with an error in its status packet."""

    def __init__(self, what: str, reason: str, error: int = 0) -> None:
        super().__init__(f"servo refused {what}: {reason}")
        self.error = error  # the status packet's error (P2 error number, P1 error bits)


class WrongModel(GripperError):  # noqa: N818
    def __init__(self, dxl_id: int, model: int, expected: int) -> None:
        super().__init__(f"servo id {dxl_id} is model {model}, expected MX-64 model {expected}")


class CommandError(GripperError, ValueError):
    """A command cannot be executed as given (bad argument, out of range, wrong state)."""


class OutOfRange(CommandError):  # noqa: N818
    def __init__(self, what: str, value: float, low: float, high: float, unit: str) -> None:
        super().__init__(f"{what} {value:g} {unit} is outside the allowed range [{low:g}, {high:g}] {unit}")


class NotReady(CommandError):  # noqa: N818
    def __init__(self, reason: str) -> None:
        super().__init__(f"gripper not ready: {reason}")


class QueueFull(CommandError):  # noqa: N818
    def __init__(self, depth: int) -> None:
        super().__init__(f"gripper busy: {depth} motion commands already queued; retry after they finish")
