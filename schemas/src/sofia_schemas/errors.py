"""Errors of the data plane. Each message says what was wrong and with which value."""

from __future__ import annotations


class SofiaError(Exception):
    """Base class of every SofIA error."""


class PointCloudError(SofiaError, ValueError):
    """A PointCloud2 message or its CDR bytes are malformed."""


class TruncatedMessage(PointCloudError):  # noqa: N818 - public API names
    def __init__(self, what: str, need: int, have: int) -> None:
        super().__init__(f"CDR buffer truncated while reading {what}: need {need} bytes, have {have}")


class UnsupportedEncoding(PointCloudError):  # noqa: N818 - public API names
    def __init__(self, what: str) -> None:
        super().__init__(what)


class MissingField(PointCloudError):  # noqa: N818 - public API names
    def __init__(self, name: str, available: list[str]) -> None:
        super().__init__(f"PointCloud2 has no field {name!r} (fields: {available})")


class SizeMismatch(PointCloudError):  # noqa: N818 - public API names
    def __init__(self, what: str) -> None:
        super().__init__(what)


class PayloadError(SofiaError, ValueError):
    """A bus payload could not be decoded into the expected message."""
