"""Errors of the detector. Each message says what was wrong, with the value."""

from __future__ import annotations

from sofia_schemas.errors import SofiaError


class DetectorError(SofiaError, ValueError):
    """Base class of every detector error; a subclass's ``template`` is filled with its arguments."""

    template = "{}"

    def __init__(self, *values: object) -> None:
        super().__init__(self.template.format(*values))


class BadCloud(DetectorError):  # noqa: N818 - public API name
    """The points given to :func:`sofia_detector.detect` cannot be a point cloud: (what)."""

    template = "bad point cloud: {}"


class UnreadableFile(DetectorError):  # noqa: N818 - public API name
    """A cloud file could not be read: (path, what)."""

    template = "{}: {}"


class DetectorBusy(DetectorError):  # noqa: N818 - public API name
    """Too many detect queries are already waiting: (waiting)."""

    template = "busy, retry: {} detect queries are already waiting for the detector"


class TransformUnavailable(DetectorError):  # noqa: N818 - public API name
    """A camera-frame cloud cannot be mapped into the base frame: (what)."""

    template = "cannot map the camera-frame cloud into the base frame: {}"


class WrongCloud(DetectorError):  # noqa: N818 - public API name
    """A cloud without a board that looks like a mistake (millimetres, camera frame): (source, what)."""

    template = "{}: no board found, and {}"


class BadSelection(DetectorError):  # noqa: N818 - public API name
    """A detect query's JSON selection cannot be understood: (what)."""

    template = "bad detect selection: {}"


class UnknownFrame(DetectorError):  # noqa: N818 - public API name
    """A cloud whose ``header.frame_id`` is neither the base frame nor a known camera frame."""

    def __init__(self, frame_id: str, source: object, known: tuple[str, ...]) -> None:
        super().__init__(
            f"{source}: cloud in frame {frame_id!r}, which is neither the base frame nor a camera frame "
            f"(known frames: {', '.join(known)})"
        )
