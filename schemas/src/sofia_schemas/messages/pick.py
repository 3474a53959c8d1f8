"""Top-down pick computed from a detection."""

from __future__ import annotations

from ..frames import BASE_FRAME
from .base import Message, Quat, Vec3


class PickTarget(Message):
    """Flange poses (base frame) for a top-down pick of one detected object.

    The flange z axis points down and the fingers close along the flange y axis, across the
    object's width; ``grasp_translation`` puts the fingertips (``fingertip_offset_m`` along the
    flange z axis) at the object's centre, ``pregrasp_translation`` is ``pregrasp_height_m`` above.
    """

    stamp_ns: int
    frame_id: str = BASE_FRAME
    object_center: Vec3
    grasp_translation: Vec3  # flange position at the grasp
    pregrasp_translation: Vec3  # flange position above the grasp
    rotation_xyzw: Quat  # flange orientation (both poses)
    yaw: float  # footprint yaw the fingers are aligned with, radians
    opening_mm: float  # gripper opening before closing: object width + margin
    field: tuple[int, int] | None = None
    object_width_mm: float | None = None  # the width the fingers close across
    fingertip_offset_m: float | None = None  # flange -> fingertip distance along the flange z axis
    pregrasp_height_m: float | None = None
