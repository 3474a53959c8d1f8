"""The JSONL sample log of older versions (``samples.jsonl``): format and recovery, for its import.

One record per line: ``{"crc32":"1a2b3c4d",<the record's members>}`` + newline, the CRC-32 over the
record without it (``{`` + the rest of the line); lines without the prefix (older logs) are read
unchecked. Bytes after the last newline are a torn write, never acknowledged. Side files:
``samples.jsonl.torn`` (cut tails, appended) and ``samples.jsonl.damaged`` (the damaged lines).
"""

from __future__ import annotations

import json
import os
import re
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

PREFIX = b'{"crc32":"'
TORN_SUFFIX = ".torn"
DAMAGED_SUFFIX = ".damaged"
_OP = re.compile(rb'"op"\s*:\s*"(\w{1,16})"')
_SAMPLE_ID = re.compile(rb'"sample_id"\s*:\s*(\d{1,18})\b')


def encode(entry: dict[str, Any]) -> bytes:
    """One log line (with its newline) for ``entry``, a non-empty JSON object of finite values."""
    body = json.dumps(entry, separators=(",", ":"), allow_nan=False).encode()
    return PREFIX + b"%08x" % zlib.crc32(body) + b'",' + body[1:] + b"\n"


def decode(raw: bytes) -> tuple[dict[str, Any], bool]:
    """(record, checksum verified) of one line without its newline; raises on any damage."""
    if raw.startswith(PREFIX):
        crc_hex, sep, body = raw[10:18], raw[18:20], b"{" + raw[20:]
        if sep != b'",' or not re.fullmatch(rb"[0-9a-f]{8}", crc_hex):
            raise ValueError("malformed checksum prefix")
        if int(crc_hex, 16) != zlib.crc32(body):
            raise ValueError(f"checksum mismatch (line says {crc_hex.decode()}, content has "
                             f"{zlib.crc32(body):08x})")  # fmt: skip
        entry, checked = json.loads(body.decode()), True
    else:
        entry, checked = json.loads(raw.decode()), False  # bytes not UTF-8: UnicodeDecodeError
    if not isinstance(entry, dict):
        raise ValueError(f"a record must be a JSON object, got {type(entry).__name__}")
    return entry, checked


@dataclass
class Damaged:
    """A line that could not be applied, why, and what it seems to have been."""

    number: int
    raw: bytes
    reason: str

    @property
    def op(self) -> str:
        """The record's op if it can still be read from the damaged bytes, else ``"?"``."""
        m = _OP.search(self.raw)
        return m.group(1).decode() if m else "?"

    @property
    def sample_id(self) -> int | None:
        m = _SAMPLE_ID.search(self.raw)
        return int(m.group(1)) if m and self.op == "add" else None


def recover(path: Path) -> list[tuple[int, bytes]]:
    """The complete lines of the log at ``path`` as (1-based number, bytes without the newline); a
    torn tail is cut off and kept in a side file."""
    data = path.read_bytes()
    end = data.rfind(b"\n") + 1
    if end < len(data):
        torn = Path(f"{path}{TORN_SUFFIX}")
        header = f"# {len(data) - end} bytes cut from {path.name} at byte {end} on {time.ctime()}\n"
        with torn.open("ab") as f:
            f.write(header.encode() + data[end:] + b"\n")
            f.flush()
            os.fsync(f.fileno())
        with path.open("r+b") as f:
            f.truncate(end)
            os.fsync(f.fileno())
    return list(enumerate(data[:end].split(b"\n")[:-1], start=1))


def keep_damaged(path: Path, damaged: list[Damaged]) -> Path:
    """Write a copy of the damaged lines (each after a ``# log:line: reason`` line) beside the log."""
    side = Path(f"{path}{DAMAGED_SUFFIX}")
    if not damaged:
        side.unlink(missing_ok=True)
        return side
    tmp = side.with_name(side.name + ".tmp")
    with tmp.open("wb") as f:
        for d in damaged:
            f.write(f"# {path.name}:{d.number}: {d.reason}\n".encode() + d.raw + b"\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, side)
    return side
