"""What travels with each cloud as its Zenoh attachment: the instants of its depth and colour,
whether they are of the same instant, and whether the calibration's depth correction is applied.

Attachment bytes: ``sofia.camera_correction=applied`` + newline + the JSON :class:`CloudMeta` when
the correction was applied (``sofia_schemas.messages.calibration.correction_applied`` is then
True, and the detector must not apply it again), else the JSON alone; a cloud in shared memory has
its location appended (:func:`sofia_runtime.shm.with_location`).
"""

from __future__ import annotations

from sofia_runtime.shm import split_location
from sofia_schemas.messages import Message
from sofia_schemas.messages.calibration import CORRECTION_APPLIED_ATTACHMENT


class CloudMeta(Message):
    """Per-cloud facts (all times bus-clock ns; device times ms of the camera's own clock)."""

    stamp_ns: int  # the cloud's stamp: the depth frame's instant
    color_stamp_ns: int | None  # the colour frame's instant (None: no colour frame)
    skew_ms: float  # colour - depth, device clock
    synced: bool  # depth and colour within the allowed skew (same instant)
    frame_number: int
    device_time_ms: float
    depth_corrected: bool = False
    correction_model: str | None = None
    depth_scale: float | None = None
    depth_offset_m: float | None = None
    correction_source: str | None = None
    filters: str = "none"
    simulated: bool = False

    def attachment(self) -> bytes:
        body = self.to_json_bytes()
        return CORRECTION_APPLIED_ATTACHMENT + b"\n" + body if self.depth_corrected else body

    @classmethod
    def from_attachment(cls, data: bytes) -> CloudMeta:
        data = split_location(data)[0] or b""
        if data.startswith(CORRECTION_APPLIED_ATTACHMENT):
            data = data[len(CORRECTION_APPLIED_ATTACHMENT) + 1 :]
        return cls.model_validate_json(data)
