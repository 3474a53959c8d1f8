"""Foxglove scene entities (3D panel) from SofIA's messages, all in the base frame.

- the board: one flat cube per field, red for the allowed fields, grey for the others;
- a detection: per object its box (centre, extents, yaw), a sphere at the centre, a smaller one at
  the centroid and a label ``row,col red`` / ``not red``;
- the pick target: arrows for the grasp and pre-grasp flange poses (the flange z axis, down);
- the calibration: the mapped blob (``target_base``) as a sphere, its 1 cm criterion as a shell.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    Pose,
    Quaternion,
    SceneEntity,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)
from sofia_schemas import Board
from sofia_schemas.frames import BASE_FRAME
from sofia_schemas.messages import CalibrationResult, Detection, PickTarget

RED = Color(r=0.85, g=0.1, b=0.1, a=0.6)
GREY = Color(r=0.6, g=0.6, b=0.6, a=0.4)
GREEN = Color(r=0.1, g=0.8, b=0.2, a=0.5)
ORANGE = Color(r=1.0, g=0.55, b=0.0, a=0.5)
BLUE = Color(r=0.2, g=0.4, b=1.0, a=0.9)
WHITE = Color(r=1.0, g=1.0, b=1.0, a=1.0)


def stamp(ns: int) -> Timestamp:
    return Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


def pose(p: Sequence[float], q_xyzw: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> Pose:
    return Pose(position=Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                orientation=Quaternion(x=float(q_xyzw[0]), y=float(q_xyzw[1]), z=float(q_xyzw[2]),
                                       w=float(q_xyzw[3])))  # fmt: skip


def yaw_q(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def board_entity(board: Board, ns: int) -> SceneEntity:
    """The configured board: its fields as thin cubes, in the board's frame (the base frame)."""
    cubes = []
    for r in range(board.rows):
        for c in range(board.cols):
            centre = board.field_center_base(r, c)
            cubes.append(CubePrimitive(
                pose=pose(tuple(centre - [0.0, 0.0, 0.001]), yaw_q(board.yaw)),
                size=Vector3(x=board.field_size[0] * 0.96, y=board.field_size[1] * 0.96, z=0.002),
                color=RED if board.is_allowed(r, c) else GREY,
            ))  # fmt: skip
    return SceneEntity(timestamp=stamp(ns), frame_id=board.frame_id, id="board", cubes=cubes)


def detection_entities(det: Detection) -> list[SceneEntity]:
    """One entity per detected object (ids ``object/<i>``), replacing the previous ones."""
    out = []
    for i, obj in enumerate(det.objects):
        colour = GREEN if obj.allowed else ORANGE
        where = f"{obj.field[0]},{obj.field[1]}" if obj.field else "off board"
        label = f"{where} {'red' if obj.allowed else 'not red'} {obj.confidence:.2f}"
        out.append(SceneEntity(
            timestamp=stamp(det.stamp_ns), frame_id=det.frame_id, id=f"object/{i}",
            lifetime=None,
            cubes=[CubePrimitive(pose=pose(obj.center, yaw_q(obj.yaw)),
                                 size=Vector3(x=obj.extents[0], y=obj.extents[1], z=obj.extents[2]), color=colour)],
            spheres=[SpherePrimitive(pose=pose(obj.center), size=Vector3(x=0.012, y=0.012, z=0.012), color=WHITE),
                     SpherePrimitive(pose=pose(obj.centroid), size=Vector3(x=0.008, y=0.008, z=0.008), color=BLUE)],
            texts=[TextPrimitive(pose=pose((obj.center[0], obj.center[1], obj.center[2] + obj.extents[2])),
                                 billboard=True, font_size=14.0, scale_invariant=True, color=WHITE, text=label)],
        ))  # fmt: skip
    return out


def pick_entity(pick: PickTarget) -> SceneEntity:
    """Arrows along the flange z axis at the grasp and pre-grasp poses."""
    # an arrow points along its pose's x axis: turn x onto the flange z axis (-90 deg about y)
    x_to_z = (0.0, -math.sqrt(0.5), 0.0, math.sqrt(0.5))
    arrows = [
        ArrowPrimitive(
            pose=pose(p, _mul(pick.rotation_xyzw, x_to_z)),
            shaft_length=0.06,
            shaft_diameter=0.006,
            head_length=0.02,
            head_diameter=0.015,
            color=c,
        )
        for p, c in ((pick.pregrasp_translation, ORANGE), (pick.grasp_translation, GREEN))
    ]
    return SceneEntity(timestamp=stamp(pick.stamp_ns), frame_id=pick.frame_id, id="pick", arrows=arrows)


def calibration_entity(result: CalibrationResult, base_frame: str = BASE_FRAME) -> SceneEntity:
    """The blob mapped into the base frame by the calibration, and the lab's 1 cm band around it."""
    p = result.target_base
    return SceneEntity(timestamp=stamp(result.stamp_ns), frame_id=base_frame, id="calibration/blob", spheres=[
        SpherePrimitive(pose=pose(p), size=Vector3(x=0.01, y=0.01, z=0.01), color=BLUE),
        SpherePrimitive(pose=pose(p), size=Vector3(x=0.02, y=0.02, z=0.02), color=Color(r=0.2, g=0.4, b=1.0, a=0.2)),
    ])  # fmt: skip


def _mul(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float, float]:
    """Quaternion product a * b, x y z w."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)  # fmt: skip
