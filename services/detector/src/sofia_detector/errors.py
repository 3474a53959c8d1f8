"""Errors of the detector. Each constructor builds a message saying what was wrong, with the value."""

from __future__ import annotations

from sofia_schemas.errors import SofiaError


class DetectorError(SofiaError, ValueError):
    """Base class of every detector error."""


class BadCloud(DetectorError):  # noqa: N818 - public API name
    """The points given to :func:`sofia_detector.detect` cannot be a point cloud."""

    def __init__(self, what: str) -> None:
        super().__init__(f"bad point cloud: {what}")


class UnreadableFile(DetectorError):  # noqa: N818 - public API name
    """A cloud file could not be read."""

    def __init__(self, path: object, what: str) -> None:
        super().__init__(f"{path}: {what}")


class DetectorBusy(DetectorError):  # noqa: N818 - public API name
    """Too many detect queries are already waiting."""

    def __init__(self, waiting: int) -> None:
        super().__init__(f"busy, retry: {waiting} detect queries are already waiting for the detector")


class TransformUnavailable(DetectorError):  # noqa: N818 - public API name
    """A camera-frame cloud cannot be mapped into the base frame."""

    def __init__(self, what: str) -> None:
        super().__init__(f"cannot map the camera-frame cloud into the base frame: {what}")


class BadTransformFile(DetectorError):  # noqa: N818 - public API name
    def __init__(self, path: object, what: str) -> None:
        super().__init__(f"transform file {path}: {what}")


class WrongCloud(DetectorError):  # noqa: N818 - public API name
    """A cloud without a board that looks like a mistake: millimetres, or the camera's frame."""

    def __init__(self, source: object, what: str) -> None:
        super().__init__(f"{source}: no board found, and {what}")


class UnknownFrame(DetectorError):  # noqa: N818 - public API name
    """A cloud whose ``header.frame_id`` is neither the base frame nor a known camera frame."""

    def __init__(self, frame_id: str, source: object, known: tuple[str, ...]) -> None:
        super().__init__(
            f"{source}: cloud in frame {frame_id!r}, which is neither the base frame nor a camera frame "
            f"(known frames: {', '.join(known)})"
        )
