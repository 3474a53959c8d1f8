"""The simulated cell's world, shared by the simulated camera, the gripper emulator and the arm
(separate processes) through one small JSON file.

The camera writes the first state (its scene's objects); the arm keeps it up to date (the object
between the fingers, the one held and carried with the flange, where a released one comes to
rest); the camera renders the objects where the file says; the emulated gripper's fingers stop at
the width of the object between them. Writes replace the file atomically; readers re-read it when
its modification time changes. The file's path comes from the ``SOFIA_SIM_WORLD`` environment
variable (or the services' ``--sim-world`` option, which sets it).

For eye-to-hand calibration the world may also hold a fixed camera mount (``T_base_cam``: the
camera then renders from there, not from the flange) and a ball on the flange (``flange_ball``:
rendered where the flange pose of each frame puts it).

Frames: base = ``panda_link0``; ``T_base_obj`` (4, 4) puts the object's centre at its origin,
its length, width and height along its x, y and z axes; metres.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict

ENV_SIM_WORLD = "SOFIA_SIM_WORLD"


class WorldObject(BaseModel):
    """One object: its shape, size, colour and pose; ``T_flange_obj`` while held."""

    model_config = ConfigDict(extra="forbid")

    id: int
    shape: str  # "box", "cylinder" or "sphere"
    extents: tuple[float, float, float]  # length, width, height (a cylinder: d, d, h; a sphere: d, d, d)
    colour: tuple[int, int, int]  # sRGB
    T_base_obj: list[list[float]]
    held: bool = False
    T_flange_obj: list[list[float]] | None = None

    def pose(self) -> np.ndarray:
        return np.array(self.T_base_obj, dtype=np.float64)

    def centre(self) -> np.ndarray:
        return self.pose()[:3, 3]


class FlangeBall(BaseModel):
    """A calibration ball fixed on the flange: its centre in the flange frame (m), radius, colour."""

    model_config = ConfigDict(extra="forbid")

    p_flange: tuple[float, float, float]
    radius_m: float
    colour: tuple[int, int, int] = (220, 90, 20)

    def centre_base(self, T_base_flange: np.ndarray) -> np.ndarray:
        """(3,) the ball's centre in the base frame at flange pose T_base_flange (4, 4)."""
        return np.asarray(T_base_flange[:3, :3] @ np.array(self.p_flange) + T_base_flange[:3, 3])


class WorldState(BaseModel):
    """The objects, the surface they rest on and what is between the fingers."""

    model_config = ConfigDict(extra="forbid")

    T_base_board: list[list[float]]  # the true board's top surface (z up); objects rest on it
    objects: list[WorldObject] = []
    between_fingers: int | None = None  # id of the object between the fingertips
    between_width_mm: float | None = None  # its width across the fingers
    version: int = 0
    T_base_cam: list[list[float]] | None = None  # a fixed camera's colour optical frame (eye-to-hand)
    flange_ball: FlangeBall | None = None  # a ball on the flange (eye-to-hand calibration target)


def world_path() -> Path | None:
    """The world file named by ``SOFIA_SIM_WORLD``, or None."""
    value = os.environ.get(ENV_SIM_WORLD)
    return Path(value) if value else None


def read_world(path: Path) -> WorldState | None:
    """The state in ``path``; None when the file does not exist (yet)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    return WorldState.model_validate(json.loads(text))


def write_world(path: Path, state: WorldState) -> None:
    """Replace ``path`` with ``state`` atomically (readers see the old or the new file)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(state.model_dump_json())
    tmp.replace(path)


class WorldFile:
    """A reader of the world file that re-reads it only when it changed."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.mtime_ns = -1
        self.state: WorldState | None = None

    def unchanged(self) -> bool:
        """Whether the file is still the one last read (a writer then replaces it, never a newer
        or a removed one)."""
        try:
            return self.path.stat().st_mtime_ns == self.mtime_ns
        except FileNotFoundError:
            return False

    def poll(self) -> bool:
        """Re-read when the file changed; True when the state is new (None once the file is gone)."""
        try:
            mtime = self.path.stat().st_mtime_ns
        except FileNotFoundError:  # removed: a new world comes with the next file
            self.mtime_ns, self.state = -1, None
            return False
        if mtime == self.mtime_ns:
            return False
        try:
            state = read_world(self.path)
        except (ValueError, OSError):
            return False  # replaced while reading: the next poll reads the new one
        self.mtime_ns, self.state = mtime, state
        return state is not None
