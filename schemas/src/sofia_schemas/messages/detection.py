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
    confidence: float = Field(ge=0.0, le=1.0)  # calibrated: >= 0.9 means within 5 mm
    visibility: float = Field(1.0, ge=0.0, le=1.0)  # estimated share of the object in view
    truncated: tuple[str, ...] = ()  # what hides the rest: image_edge, occluded, depth_holes
    colour: str | None = None  # palette name of the object's colour (None: no colours in the cloud)
    rgb: tuple[int, int, int] | None = None  # its white-balanced mean sRGB


class Detection(Message):
    """Detector result for one cloud.

    ``status``: ``ok`` (objects found), ``no_object`` (the board is seen and empty) or ``no_board``
    (no board surface near the configured board: nothing can be said; ``detail`` tells why).
    """

    stamp_ns: int  # stamp of the cloud
    frame_id: str
    status: Literal["ok", "no_object", "no_board"]
    objects: list[DetectedObject] = []  # allowed fields first
    board_normal: Vec3 | None = None  # measured board plane normal, base frame
    board_offset_m: float | None = None  # measured plane height at the board centre minus surface_z
    board_center: Vec3 | None = None  # measured board centre on its surface, base frame
    board_yaw: float | None = None  # measured board yaw about the base z axis, radians
    timings_ms: dict[str, float] = {}
    transform: str | None = None  # which flange->camera transform was used (camera-frame clouds)
    source: str | None = None  # key expression or file the cloud came from
    detail: str = ""  # why there is no result, or what was approximated
