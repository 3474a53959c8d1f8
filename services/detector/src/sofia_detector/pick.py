"""Top-down pick of a detected object: flange poses for the grasp and the pre-grasp, and the opening.

Convention: the flange z axis points down (towards the board) and the fingers close along the
flange y axis, across the object's width; the flange x axis lies along the object's length.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from sofia_schemas.messages import DetectedObject, Detection, PickTarget
from sofia_schemas.transforms import matrix_to_quat_xyzw

log = logging.getLogger("sofia.detector")


@dataclass(frozen=True)
class PickParams:
    """How a detected object is picked (metres, radians, millimetres as named)."""

    fingertip_offset: float = 0.20  # flange -> fingertips along the flange z axis
    pregrasp_height: float = 0.10  # the pre-grasp pose above the grasp
    margin_mm: float = 20.0  # added to the object's width for the opening
    max_opening_mm: float | None = None  # the gripper's widest opening (the opening is clipped to it)
    yaw_offset: float = 0.0  # turn of the fingers about the flange z axis from the flange y axis
    # objects below it get no pick: a truncated object's centre is that of its visible part (its
    # confidence is below 0.5) and may lie centimetres off
    min_confidence: float = 0.5


def pick_target(
    obj: DetectedObject, stamp_ns: int, frame_id: str = "panda_link0", params: PickParams | None = None
) -> PickTarget:
    """The top-down pick of ``obj`` (base frame, metres)."""
    params = params or PickParams()
    yaw = float(obj.yaw)
    c, s = np.cos(yaw + params.yaw_offset), np.sin(yaw + params.yaw_offset)
    # R_base_flange, columns x = (c, s, 0), y = (s, -c, 0), z = (0, 0, -1): pointing down, det +1
    R = np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])
    center = np.asarray(obj.center, dtype=np.float64)
    grasp = center - R[:, 2] * params.fingertip_offset  # fingertips at the centre
    pregrasp = grasp + np.array([0.0, 0.0, params.pregrasp_height])
    width_mm = float(min(obj.extents[0], obj.extents[1])) * 1e3
    opening = width_mm + params.margin_mm
    if params.max_opening_mm is not None:
        opening = min(opening, params.max_opening_mm)
    q = matrix_to_quat_xyzw(R)
    return PickTarget(
        stamp_ns=stamp_ns, frame_id=frame_id,
        object_center=tuple(float(v) for v in center),  # type: ignore[arg-type]
        grasp_translation=tuple(float(v) for v in grasp),  # type: ignore[arg-type]
        pregrasp_translation=tuple(float(v) for v in pregrasp),  # type: ignore[arg-type]
        rotation_xyzw=tuple(float(v) for v in q),  # type: ignore[arg-type]
        yaw=yaw, opening_mm=round(opening, 2), field=obj.field, object_width_mm=round(width_mm, 2),
        fingertip_offset_m=params.fingertip_offset, pregrasp_height_m=params.pregrasp_height,
    )  # fmt: skip


def pickable(detection: Detection, params: PickParams | None = None) -> list[DetectedObject]:
    """The objects on an allowed (red) field whose confidence is at least ``min_confidence``, in
    the detection's order."""
    floor = (params or PickParams()).min_confidence
    return [obj for obj in detection.objects if obj.allowed and obj.confidence >= floor]


def first_pick(detection: Detection, params: PickParams | None = None) -> PickTarget | None:
    """The pick of the first object :func:`pickable`, or None when there is none (no object on an
    allowed field, or only ones whose centre is not trusted)."""
    objects = pickable(detection, params)
    return pick_target(objects[0], detection.stamp_ns, detection.frame_id, params) if objects else None


class Picks:
    """The pick target of each detection (:func:`first_pick`), counted: ``published``, and
    ``withheld`` (detections with objects on red fields, none of them :func:`pickable`). A run of
    withheld ones is logged once, not at the camera's rate."""

    def __init__(self, params: PickParams) -> None:
        self.params = params
        self.published = 0
        self.withheld = 0
        self._withholding = False

    def of(self, detection: Detection, source: str) -> PickTarget | None:
        """The pick target of ``detection`` (of the cloud from ``source``), or None."""
        pick = first_pick(detection, self.params)
        red = [obj.confidence for obj in detection.objects if obj.allowed]
        withholding = pick is None and bool(red)
        self.published += pick is not None
        self.withheld += withholding
        if withholding and not self._withholding:
            log.info(
                "no pick target for the cloud on %s: its objects on red fields have confidence %s, below "
                "%.2f (truncated or barely seen: their centres are not trusted)",
                source, red, self.params.min_confidence,
            )  # fmt: skip
        self._withholding = withholding
        return pick
