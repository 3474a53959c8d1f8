"""The arm's part of the simulated world (:mod:`sofia_schemas.sim_world`): which object is between
the fingertips, the object held (carried with the flange while the gripper reports a grasp) and
where a released one comes to rest (on the board's surface below the fingertips, upright, keeping
its yaw).

Frames: base = ``panda_link0``, flange = ``panda_link8`` (the fingertips ``fingertip_offset_m``
along its z axis; the fingers close along its y axis), board = the true board's top surface.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import numpy as np
import zenoh
from sofia_schemas.messages import GripperState
from sofia_schemas.sim_world import WorldFile, WorldObject, write_world
from sofia_schemas.transforms import invert

log = logging.getLogger(__name__)
TICK_S = 0.05
CONTACT_M = 0.005  # the fingertips count as between the fingers' object this far beyond its faces
RELEASE_MM = 3.0  # the fingers opened this much wider than the held object: it is let go


def between(obj: WorldObject, p_tip_base: np.ndarray) -> bool:
    """Whether the fingertips' point p_tip_base (3,) (base frame) lies within ``obj``'s bounds."""
    p = invert(obj.pose()) @ np.r_[p_tip_base, 1.0]
    return bool(np.all(np.abs(p[:3]) <= np.array(obj.extents) / 2 + CONTACT_M))


def width_across(obj: WorldObject, T_base_flange: np.ndarray) -> float:
    """The object's extent (m) along the flange y axis, the direction the fingers close in."""
    if obj.shape != "box":
        return float(obj.extents[0])
    y_obj = obj.pose()[:3, :3].T @ T_base_flange[:3, 1]
    return float(np.abs(y_obj[:2]) @ np.array(obj.extents[:2]))


def resting_pose(obj: WorldObject, T_base_board: np.ndarray) -> np.ndarray:
    """(4, 4) the pose of ``obj`` set down on the board's surface below its centre, upright on it,
    keeping its yaw about the board normal."""
    T_board_obj = invert(T_base_board) @ obj.pose()
    x = T_board_obj[:3, 0]
    yaw = float(np.arctan2(x[1], x[0]))
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = [T_board_obj[0, 3], T_board_obj[1, 3], obj.extents[2] / 2]
    return np.asarray(T_base_board @ T)


class WorldKeeper:
    """Keeps the world file up to date from the flange pose and the gripper state (thread)."""

    def __init__(self, path: Path, fingertip_offset_m: float) -> None:
        self.file = WorldFile(path)
        self.offset = fingertip_offset_m
        self.T_base_flange: np.ndarray | None = None
        self.gripper: GripperState | None = None
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="sim-world", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2.0)

    def _run(self) -> None:
        while not self.stop.wait(TICK_S):
            try:
                self.tick()
            except (OSError, ValueError) as e:
                log.warning("simulated world %s: %s", self.file.path, e)

    def tick(self) -> None:
        """One update: the object between the fingers, grasped, carried or released."""
        self.file.poll()
        state, T, g = self.file.state, self.T_base_flange, self.gripper
        if state is None or T is None:
            return
        new = state.model_copy(deep=True)
        p_tip = T[:3, 3] + T[:3, 2] * self.offset
        held = next((o for o in new.objects if o.held), None)
        if held is not None:
            held.T_base_obj = (T @ np.array(held.T_flange_obj)).tolist()
            width_mm = 1e3 * width_across(held, T)
            opening = g.opening_mm if g is not None and g.opening_mm is not None else np.inf
            if g is not None and not g.grasped and opening > width_mm + RELEASE_MM:
                held.held, held.T_flange_obj = False, None
                held.T_base_obj = resting_pose(held, np.array(new.T_base_board)).tolist()
                log.info(
                    "simulated world: object %d released at %s m",
                    held.id,
                    np.round(held.centre(), 4).tolist(),
                )
        inside = [o for o in new.objects if o.held or between(o, p_tip)]
        obj = inside[0] if inside else None
        new.between_fingers = None if obj is None else obj.id
        new.between_width_mm = None if obj is None else round(1e3 * width_across(obj, T), 2)
        if obj is not None and not obj.held and g is not None and g.grasped:
            obj.held, obj.T_flange_obj = True, (invert(T) @ obj.pose()).tolist()
            log.info("simulated world: object %d grasped", obj.id)
        if new.model_dump() != state.model_dump() and self.file.unchanged():
            new.version = state.version + 1
            write_world(self.file.path, new)
            self.file.poll()

    def on_pose(self, T_base_flange: np.ndarray) -> None:
        self.T_base_flange = T_base_flange

    def on_gripper_sample(self, sample: zenoh.Sample) -> None:
        try:
            self.gripper = GripperState.model_validate_json(sample.payload.to_bytes())
        except ValueError:
            pass
