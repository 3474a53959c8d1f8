"""Errors of the camera package; each message says what was wrong and with which value."""

from __future__ import annotations

from sofia_schemas.errors import SofiaError


class CameraError(SofiaError):
    """Base class of camera errors."""


class CameraUnavailable(CameraError):  # noqa: N818 - public API name
    """No camera (or not the one asked for) can be opened now; the service retries."""

    def __init__(self, what: str) -> None:
        super().__init__(f"camera unavailable: {what}")


class FramesStopped(CameraError):  # noqa: N818 - public API name
    """A streaming camera delivered no frame for too long (unplugged, USB reset, power)."""

    def __init__(self, serial: str, seconds: float) -> None:
        super().__init__(f"camera {serial} delivered no frame for {seconds:.1f} s (unplugged?)")


class UnsupportedMode(CameraError, ValueError):  # noqa: N818 - public API name
    def __init__(self, width: int, height: int, fps: int, supported: list[str]) -> None:
        super().__init__(f"camera mode {width}x{height} @ {fps} Hz is not supported; use one of {supported}")


class BadOption(CameraError, ValueError):  # noqa: N818 - public API name
    """A command-line or config value is invalid."""

    def __init__(self, option: str, value: object, why: str) -> None:
        super().__init__(f"{option} {value!r}: {why}")


class UnsupportedIntrinsics(CameraError, ValueError):  # noqa: N818 - public API name
    def __init__(self, model: str) -> None:
        super().__init__(
            f"distortion model {model!r} is not supported for deprojection "
            "(none, brown_conrady, inverse_brown_conrady are)"
        )
