"""Errors of the live view. Each constructor builds a message saying what was wrong, with the value."""

from __future__ import annotations

from sofia_schemas.errors import SofiaError


class VizError(SofiaError, ValueError):
    """Base class of every viz error."""


class PortInUse(VizError):  # noqa: N818 - public API name
    def __init__(self, host: str, port: int, what: str) -> None:
        super().__init__(f"cannot serve Foxglove on {host}:{port}: {what}")
