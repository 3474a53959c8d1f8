"""Common base of every JSON message on the bus."""

from __future__ import annotations

import math
import time
from typing import Annotated, Final, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict

SCHEMA_VERSION: Final = 1


def _finite(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError(f"must be finite, got {v}")
    return v


Finite = Annotated[float, AfterValidator(_finite)]
Vec3 = tuple[Finite, Finite, Finite]
Quat = tuple[Finite, Finite, Finite, Finite]


def _unit(q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    n = math.hypot(*q)  # one quaternion per message: no array
    if abs(n - 1.0) > 1e-3:
        raise ValueError(f"quaternion (x y z w) {q} has norm {n:.6f}, expected 1")
    return q


UnitQuat = Annotated[Quat, AfterValidator(_unit)]
Matrix4 = tuple[tuple[Finite, Finite, Finite, Finite], ...]


def now_ns() -> int:
    """Wall-clock time in integer nanoseconds."""
    return time.time_ns()


class Message(BaseModel):
    """Base of bus messages: strict fields and a schema version."""

    model_config = ConfigDict(extra="forbid")

    schema_version: Literal[1] = SCHEMA_VERSION

    def to_json_bytes(self) -> bytes:
        return self.model_dump_json().encode()


class ErrorReply(Message):
    """Error reply of a queryable (sent with ``reply_err``)."""

    error: str  # exception class or error kind, e.g. "PayloadError"
    message: str  # what was wrong, with the offending value
    key: str | None = None


class ServiceStatus(Message):
    """Health and counters of a service."""

    service: str
    stamp_ns: int
    state: Literal["starting", "ok", "degraded", "error", "stopping"] = "ok"
    detail: str = ""
    counters: dict[str, int] = {}
    info: dict[str, str | float | int | bool | None] = {}
