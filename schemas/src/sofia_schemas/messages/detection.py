"""Detector output."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Message, Vec3


class DetectedObject(Message):
    """One object on the board, base frame, metres."""

    center: Vec3  # centre of the estimated bounding box
    centroid: Vec3  # mean of the visible points (the lab's definition)
    extents: Vec3  # length, width, height
    yaw: float  # footprint yaw about the board normal, radians, base frame
    field: tuple[int, int] | None  # (row, col), None when off the board grid
    allowed: bool  # lies on a red field
    n_points: int
    confidence: float = Field(ge=0.0, le=1.0)


class Detection(Message):
    """Detector result for one cloud. ``status`` is ``no_object`` on an empty board."""

    stamp_ns: int  # stamp of the cloud
    frame_id: str
    status: Literal["ok", "no_object"]
    objects: list[DetectedObject] = []  # allowed fields first
    board_normal: Vec3 | None = None  # measured board plane normal, base frame
    board_offset_m: float | None = None  # measured plane height at the board centre minus surface_z
    timings_ms: dict[str, float] = {}
    transform: str | None = None  # which flange->camera transform was used (camera-frame clouds)
    source: str | None = None  # key expression or file the cloud came from
