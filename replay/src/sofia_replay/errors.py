"""Errors of recordings and replay. Each message says what was wrong and with which value."""

from __future__ import annotations

from pathlib import Path

from sofia_schemas.errors import SofiaError


class RecordingError(SofiaError, ValueError):
    """A recording cannot be read or written."""


class RecordingNotFoundError(RecordingError, FileNotFoundError):
    def __init__(self, path: Path | str) -> None:
        super().__init__(f"recording {str(path)!r} does not exist")


class NotAnMcapError(RecordingError):
    def __init__(self, path: Path | str, reason: str) -> None:
        super().__init__(f"{str(path)!r} is not a readable MCAP file: {reason}")


class UnknownSchemaError(RecordingError):
    def __init__(self, typename: str) -> None:
        super().__init__(f"no ROS 2 message definition for type {typename!r}")


class BadTruthError(RecordingError):
    def __init__(self, path: Path | str, reason: str) -> None:
        super().__init__(f"ground truth metadata of {str(path)!r} is invalid: {reason}")


class BadMappingError(RecordingError):
    def __init__(self, text: str, reason: str) -> None:
        super().__init__(f"topic mapping {text!r} is invalid: {reason}")


class BadBagError(RecordingError):
    def __init__(self, path: Path | str, reason: str) -> None:
        super().__init__(f"{str(path)!r} is not a readable ROS 1 bag: {reason}")
