"""Top-down pick computed from a detection."""

from __future__ import annotations

from .base import Message, Quat, Vec3


class PickTarget(Message):
    """Flange poses (base frame) for a top-down pick of one detected object."""

    stamp_ns: int
    frame_id: str = "panda_link0"
    object_center: Vec3
    grasp_translation: Vec3  # flange position at the grasp
    pregrasp_translation: Vec3  # flange position above the grasp
    rotation_xyzw: Quat  # flange orientation (both poses)
    yaw: float  # footprint yaw the fingers are aligned with, radians
    opening_mm: float  # gripper opening before closing: object width + margin
    field: tuple[int, int] | None = None
