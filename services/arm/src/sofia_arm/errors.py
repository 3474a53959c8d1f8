"""Errors of the arm package; each message says what was wrong and with which value."""

from __future__ import annotations

from sofia_schemas.errors import SofiaError


class ArmError(SofiaError):
    """Base class of arm errors."""


class ConfigError(ArmError, ValueError):
    """The arm configuration is missing or invalid."""


class TargetRefused(ArmError, ValueError):  # noqa: N818
    """A motion target breaks a safety rule; nothing moved."""


class OutsideWorkspace(TargetRefused):
    def __init__(self, what: str, p_base: object, low: object, high: object) -> None:
        super().__init__(
            f"{what}: flange position {p_base} m is outside the workspace box [{low}, {high}] m (base frame)"
        )


class BelowSurface(TargetRefused):
    def __init__(self, what: str, tool: str, p_base: object, lowest_allowed: float, surface: str,
                 margin: float) -> None:  # fmt: skip
        super().__init__(
            f"{what}: the {tool} would reach {p_base} m (base frame), below the surface ({surface}) "
            f"plus its margin of {margin:.3f} m: z must stay >= {lowest_allowed:.4f} m"
        )


class OutsideJointLimits(TargetRefused):
    def __init__(
        self, joint: int, value: float, low: float, high: float, margin: float, what: str = ""
    ) -> None:
        super().__init__(
            f"{what + ': ' if what else ''}joint {joint} target {value:.4f} rad is outside the allowed range [{low:.4f}, {high:.4f}] rad "
            f"(joint limits minus a margin of {margin:.3f} rad)"
        )


class Unreachable(TargetRefused):
    def __init__(self, what: str, reason: str) -> None:
        super().__init__(f"{what} is not reachable: {reason}")


class NotReady(ArmError):  # noqa: N818
    """The arm cannot move now (not connected, in error, the gripper in error)."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"arm not ready: {reason}")


class Unavailable(ArmError):  # noqa: N818
    """A command whose implementation is not installed."""

    def __init__(self, command: str, module: str, cause: object) -> None:
        super().__init__(f"{command} is not available: module {module} could not be loaded ({cause})")


class SimError(ArmError):
    """franky-sim could not be started."""


class PhaseFailed(Exception):  # noqa: N818 - a compound command's control flow, never seen by users
    """A step of a compound command ended without reaching its goal; the command reports it."""

    def __init__(self, phase: str, reason: str, status: str = "failed") -> None:
        super().__init__(f"{phase}: {reason}")
        self.phase, self.reason, self.status = phase, reason, status
