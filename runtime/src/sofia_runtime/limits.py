"""How much a service accepts and how much it echoes back, in one place.

- :func:`clip`: what an error reply or a log line quotes of a value: its first ``ECHO_CHARS``
  characters and the count of the rest, so a 2 MB payload never becomes a 20 MB error;
- :func:`error_text`: the message of an error as replied and logged (a pydantic ``ValidationError``
  is summarised: its first errors, each input clipped, and how many more there are);
- :func:`payload_limit`: the largest payload a key accepts, from ``$SOFIA_PAYLOAD_LIMITS``
  (``KEYEXPR=BYTES`` pairs, comma-separated, first match wins, e.g.
  ``sofia/*/gripper/command=4096,sofia/**=1e6``), else :data:`DEFAULT_LIMITS`;
- :class:`ClipFilter`: a logging filter that clips every record (message and traceback).
"""

from __future__ import annotations

import functools
import logging
import os

import zenoh
from pydantic import ValidationError
from sofia_schemas.errors import PayloadError

ECHO_CHARS = 200  # characters of an offending value quoted in an error
MESSAGE_CHARS = 2000  # characters of a whole error message or log line
TRACEBACK_CHARS = 8000
ERRORS_SHOWN = 3  # errors of a ValidationError spelt out
ENV_LIMITS = "SOFIA_PAYLOAD_LIMITS"
MIB = 1 << 20
# point clouds (a 1280x720 xyz+rgb cloud is 14.7 MB) and detect queries carrying one; JSON messages
DEFAULT_LIMITS: tuple[tuple[str, int], ...] = (
    ("sofia/*/points", 64 * MIB),
    ("sofia/*/camera/points", 64 * MIB),
    ("sofia/*/detector/detect", 64 * MIB),
    ("**", 256 * 1024),
)


class PayloadTooLarge(PayloadError):  # noqa: N818 - public API names
    def __init__(self, key: str, size: int, limit: int) -> None:
        super().__init__(
            f"payload on {key} has {size} bytes, more than its limit of {limit} bytes "
            f"(${ENV_LIMITS} sets the limits per key)"
        )


def clip(value: object, chars: int = ECHO_CHARS) -> str:
    """``value`` as text (``repr`` for bytes), at most ``chars`` characters and the count of the rest."""
    text = repr(value) if isinstance(value, bytes | bytearray | memoryview) else str(value)
    if len(text) <= chars:
        return text
    return f"{text[:chars]}… ({len(text) - chars} more characters)"


def error_text(error: BaseException | str) -> str:
    """The message of ``error`` as a reply or a log line shows it, clipped."""
    if isinstance(error, ValidationError):
        errors = error.errors(include_url=False)
        parts = [
            f"{'.'.join(str(p) for p in e['loc']) or '(root)'}: {e['msg']} (input {clip(e.get('input'))})"
            for e in errors[:ERRORS_SHOWN]
        ]
        more = f"; and {len(errors) - ERRORS_SHOWN} more" if len(errors) > ERRORS_SHOWN else ""
        return clip(
            f"{len(errors)} validation errors for {error.title}: {'; '.join(parts)}{more}", MESSAGE_CHARS
        )
    return clip(error, MESSAGE_CHARS)


def _parse(text: str) -> list[tuple[str, int]]:
    out = []
    for item in (i.strip() for i in text.split(",")):
        if not item:
            continue
        key, sep, size = item.rpartition("=")
        try:
            limit = int(float(size))
            zenoh.KeyExpr(key)
        except (ValueError, zenoh.ZError):
            raise ValueError(f"${ENV_LIMITS}: {clip(item)!r} is not KEYEXPR=BYTES") from None
        if not sep or limit < 0:
            raise ValueError(f"${ENV_LIMITS}: {clip(item)!r} is not KEYEXPR=BYTES")
        out.append((key, limit))
    return out


def payload_limit(key: str, env: dict[str, str] | None = None) -> int:
    """The largest payload, in bytes, accepted on ``key``."""
    return _limit(key, (os.environ if env is None else env).get(ENV_LIMITS, ""))


@functools.lru_cache(maxsize=1024)
def _limit(key: str, spec: str) -> int:
    """:func:`payload_limit` of ``key`` under ``$SOFIA_PAYLOAD_LIMITS`` = ``spec`` (kept: every
    sample on a key asks again)."""
    for pattern, limit in (*_parse(spec), *DEFAULT_LIMITS):
        if zenoh.KeyExpr(pattern).includes(key):
            return limit
    raise AssertionError("DEFAULT_LIMITS ends with '**'")  # pragma: no cover


def check_payload(key: str, payload: zenoh.ZBytes | bytes | None) -> None:
    """Raise :class:`PayloadTooLarge` when ``payload`` exceeds the limit of ``key``."""
    size = 0 if payload is None else len(payload)
    limit = payload_limit(key)
    if size > limit:
        raise PayloadTooLarge(key, size, limit)


class ClipFilter(logging.Filter):
    """Clips each record's message to ``MESSAGE_CHARS`` and its traceback to ``TRACEBACK_CHARS``."""

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        if len(message) > MESSAGE_CHARS:
            record.msg, record.args = clip(message, MESSAGE_CHARS), None
        if record.exc_info and not record.exc_text:
            text = logging.Formatter().formatException(record.exc_info)
            record.exc_text = clip(text, TRACEBACK_CHARS)
        return True
