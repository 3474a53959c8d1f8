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


class NoSuchTopicError(RecordingError):
    def __init__(self, path: Path | str, missing: list[str], topics: list[str]) -> None:
        super().__init__(
            f"{str(path)!r} has no topic {', '.join(missing)} (its topics: {', '.join(topics) or 'none'})"
        )


class NoSuchMessageError(RecordingError):
    def __init__(self, path: Path | str, topic: str, index: int, count: int) -> None:
        super().__init__(
            f"{str(path)!r} has {count} messages on {topic}: index {index} is not in 0..{count - 1}"
            if count
            else f"{str(path)!r} has no message on {topic}"
        )


class NothingConvertedError(RecordingError):
    def __init__(self, path: Path | str, reason: str) -> None:
        super().__init__(f"nothing to convert in {str(path)!r}: {reason}; no MCAP written")
