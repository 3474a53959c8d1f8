"""Stamped poses and point-cloud metadata."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ..frames import BASE_FRAME, CAMERA_FRAME, FLANGE_FRAME
from .base import Message, UnitQuat, Vec3


class FlangePose(Message):
    """Stamped pose of the flange in the base frame: ``T_base_flange`` (frame_id -> child_frame_id)."""

    stamp_ns: int
    frame_id: str = BASE_FRAME
    child_frame_id: str = FLANGE_FRAME
    translation: Vec3
    rotation_xyzw: UnitQuat

    def matrix(self) -> np.ndarray:
        """(4, 4) ``T_base_flange``."""
        from ..transforms import make_transform

        return make_transform(np.array(self.translation), np.array(self.rotation_xyzw))

    @classmethod
    def from_matrix(
        cls, T_base_flange: np.ndarray, stamp_ns: int, frame_id: str = BASE_FRAME,
        child_frame_id: str = FLANGE_FRAME,
    ) -> FlangePose:  # fmt: skip
        from ..transforms import as_transforms, matrix_to_quat_xyzw

        T = as_transforms(T_base_flange, "T_base_flange")
        q = matrix_to_quat_xyzw(T[:3, :3])
        return cls(
            stamp_ns=stamp_ns, frame_id=frame_id, child_frame_id=child_frame_id,
            translation=tuple(float(v) for v in T[:3, 3]),  # type: ignore[arg-type]
            rotation_xyzw=tuple(float(v) for v in q),  # type: ignore[arg-type]
        )  # fmt: skip


class PointCloudInfo(Message):
    """Metadata of a PointCloud2 (what ``sofia echo`` prints for a cloud)."""

    stamp_ns: int
    frame_id: str
    height: int
    width: int
    fields: list[str]
    point_step: int
    n_points: int
    n_finite: int
    is_dense: bool


class BlobObservation(Message):
    """Position of the calibration blob in the camera optical frame."""

    stamp_ns: int
    frame_id: str = CAMERA_FRAME
    position: Vec3  # metres, camera optical frame
    confidence: float = Field(1.0, ge=0.0, le=1.0)
    n_pixels: int = 0
