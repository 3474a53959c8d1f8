"""The world the simulated D435 looks at: the calibration blob sheet or the board with objects,
built with the project's Open3D ray caster (``sofia_replay.synth``), or the eye-to-hand cell (a
fixed camera and a ball on the flange, :mod:`sofia_camera.sim_fixed`), or a ball on the table for
the flange camera (``ball``), and its ground truth.

Everything is in the robot base frame (metres). The board scene is deterministic in its seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from sofia_replay.synth.calibration import TABLE_Z, CalibrationTarget
from sofia_replay.synth.scene import DEFAULT_T_FLANGE_CAM, ObjectTruth, Scene, build, make_scene
from sofia_schemas import Board
from sofia_schemas.files import FileContentError, load_json_or_yaml
from sofia_schemas.sim_world import WorldFile, WorldObject, WorldState, write_world
from sofia_schemas.transforms import as_transforms, make_transform

from .errors import BadOption
from .sim_fixed import (
    DEFAULT_BALL_FLANGE,
    DEFAULT_BALL_RADIUS,
    DEFAULT_T_BASE_CAM,
    FixedCameraCell,
    eye_to_hand_state,
    table_and_ball,
)

SceneName = Literal["calibration", "board", "eye-to-hand", "ball"]
SCENES: tuple[SceneName, ...] = ("calibration", "board", "eye-to-hand", "ball")
KINDS = ("one", "two", "nonred", "empty", "sort")
# the lab's sorting task: a yellow, a green and a blue object, and a distractor of another colour
SORT_COLOURS = (("yellow", (230, 200, 40)), ("green", (40, 160, 60)), ("blue", (30, 80, 200)),
                ("purple", (150, 60, 170)))  # fmt: skip
DEFAULT_TARGET = (0.45, 0.25, TABLE_Z + 0.0005)


def parse_T_flange_cam(
    text: str | None, option: str = "--sim-T-flange-cam", default: np.ndarray = DEFAULT_T_FLANGE_CAM
) -> np.ndarray:
    """(4, 4) ``T_flange_cam`` (or the transform of ``option``, e.g. ``T_base_cam``) from ``"x y z qx qy qz qw"`` (metres, quaternion x y z w; commas
    allowed) or a YAML/JSON file with ``matrix`` (4x4) or ``translation`` + ``quaternion_xyzw``;
    None gives ``default``. BadOption says what is wrong."""
    if text is None:
        return np.array(default, dtype=np.float64)
    parts = text.replace(",", " ").split()
    try:
        if len(parts) == 7:
            values = np.array([float(v) for v in parts])
            return make_transform(values[:3], values[3:])
        data: Any = load_json_or_yaml(Path(text))
    except (ValueError, OSError, FileContentError) as e:
        raise BadOption(option, text, f"not 7 numbers 'x y z qx qy qz qw' nor a readable file: {e}") from None
    if not isinstance(data, dict):
        raise BadOption(option, text, "file must hold a mapping")
    try:
        if "matrix" in data:
            return as_transforms(np.array(data["matrix"], float), "matrix", tol=1e-4)
        return make_transform(np.array(data["translation"], float), np.array(data["quaternion_xyzw"], float))
    except (KeyError, ValueError, TypeError) as e:
        raise BadOption(option, text, f"needs 'matrix' or 'translation' + 'quaternion_xyzw': {e}") from None


def sort_objects(board: Board, T_base_board: np.ndarray, rng: np.random.Generator) -> list[ObjectTruth]:
    """The sorting task's objects: one of each of ``SORT_COLOURS``, boxes and cylinders 4-6 cm wide
    and 5-7 cm high, each on its own field of the board's first two rows (the last row stays free
    for the places)."""
    fields = [(r, c) for r in range(min(2, board.rows)) for c in range(board.cols)]
    picked = rng.choice(len(fields), size=len(SORT_COLOURS), replace=False)
    objects = []
    for (_, colour), k in zip(SORT_COLOURS, picked, strict=True):
        r, c = fields[int(k)]
        shape = "box" if rng.random() < 0.5 else "cylinder"
        ext = (
            rng.uniform(0.04, 0.06, 3)
            if shape == "box"
            else np.r_[np.full(2, rng.uniform(0.04, 0.06)), rng.uniform(0.04, 0.06)]
        )
        xy = board.field_centers_board()[r, c] + rng.uniform(-0.02, 0.02, 2)
        yaw = rng.uniform(-np.pi / 2, np.pi / 2)
        c_, s_ = np.cos(yaw), np.sin(yaw)
        T_board_obj = np.array(
            [[c_, -s_, 0, xy[0]], [s_, c_, 0, xy[1]], [0, 0, 1, ext[2] / 2], [0, 0, 0, 1.0]]
        )
        T = T_base_board @ T_board_obj
        objects.append(ObjectTruth(shape=shape, center=T[:3, 3].copy(), extents=ext, yaw=float(np.arctan2(T[1, 0], T[0, 0])),  # type: ignore[arg-type]
                                   field=(r, c), allowed=board.is_allowed(r, c), T_base_obj=T, colour=colour))  # fmt: skip
    return objects


def world_of(scene: Scene) -> WorldState:
    """The first state of the shared world: the scene's objects on its true board."""
    objects = [WorldObject(id=i, shape=o.shape, extents=tuple(map(float, o.extents)), colour=o.colour,  # type: ignore[arg-type]
                           T_base_obj=o.T_base_obj.tolist()) for i, o in enumerate(scene.objects)]  # fmt: skip
    return WorldState(T_base_board=scene.T_base_board.tolist(), objects=objects)


def object_of(obj: WorldObject) -> ObjectTruth:
    """The ray caster's object of a world object where the world says it is."""
    T = obj.pose()
    return ObjectTruth(shape=obj.shape, center=T[:3, 3].copy(), extents=np.array(obj.extents),  # type: ignore[arg-type]
                       yaw=float(np.arctan2(T[1, 0], T[0, 0])), field=(-1, -1), allowed=False, T_base_obj=T,
                       colour=obj.colour)  # fmt: skip


@dataclass
class SimOptions:
    """The ``--sim-*`` options (see ``sofia camera serve --help``)."""

    scene: SceneName = "calibration"
    T_flange_cam: np.ndarray = field(default_factory=lambda: DEFAULT_T_FLANGE_CAM.copy())
    target_base: tuple[float, float, float] = DEFAULT_TARGET
    blob_radius: float = 0.015
    seed: int = 0
    kind: str = "one"
    board_file: Path | None = None
    noise: bool = True
    stereo: bool = False  # replay's active-stereo D435 model instead of the simple noise
    world_file: Path | None = None  # the simulated world shared with the arm and the gripper (board scene)
    T_base_cam: np.ndarray = field(default_factory=lambda: DEFAULT_T_BASE_CAM.copy())  # eye-to-hand mount
    ball_flange: tuple[float, float, float] = DEFAULT_BALL_FLANGE  # eye-to-hand: ball centre, flange frame
    ball_radius: float = DEFAULT_BALL_RADIUS

    def __post_init__(self) -> None:
        if self.scene not in SCENES:
            raise BadOption("--sim-scene", self.scene, f"use one of {list(SCENES)}")
        if self.kind not in KINDS:
            raise BadOption("--sim-kind", self.kind, f"use one of {list(KINDS)}")
        if not 0.001 <= self.blob_radius <= 0.1:
            raise BadOption("--sim-blob-radius", self.blob_radius, "must be within [0.001, 0.1] m")
        self.T_flange_cam = as_transforms(np.asarray(self.T_flange_cam, float), "T_flange_cam", tol=1e-4)
        self.T_base_cam = as_transforms(np.asarray(self.T_base_cam, float), "T_base_cam", tol=1e-4)
        if not 0.005 <= self.ball_radius <= 0.1 or np.linalg.norm(self.ball_flange) > 0.4:
            raise BadOption("--sim-ball", [*self.ball_flange, self.ball_radius],
                            "radius must be within [0.005, 0.1] m and the centre within 0.4 m of the flange")  # fmt: skip


class SimWorld:
    """The ray-casting scene, the colour of each hit, and the truth of one :class:`SimOptions`."""

    def __init__(self, options: SimOptions) -> None:
        self.options = options
        self.fixed: FixedCameraCell | None = None
        if options.scene == "eye-to-hand":
            state = eye_to_hand_state(options.T_base_cam, options.ball_flange, options.ball_radius)
            self.fixed = FixedCameraCell(
                state, None if options.world_file is None else WorldFile(options.world_file)
            )
            self.raycasting, self.colour_of = self.fixed.scene_at(np.eye(4))
            self.scene = None
        elif options.scene == "ball":  # on the table at the target's x y (its z: resting on the table)
            x, y, z = options.target_base
            on_table = z if z > TABLE_Z + options.ball_radius - 1e-3 else TABLE_Z + options.ball_radius
            self.ball_base = np.array([x, y, on_table])
            self.raycasting, self.colour_of = table_and_ball(self.ball_base, options.ball_radius)
            self.scene = None
        elif options.scene == "calibration":
            self.target = CalibrationTarget(
                p_base=np.array(options.target_base, float), radius=options.blob_radius
            )
            self.raycasting, self.colour_of = self.target.build()
            self.scene = None
        else:
            board = Board.from_file(options.board_file) if options.board_file else Board.default()
            rng = np.random.default_rng(options.seed)
            kind = "empty" if options.kind == "sort" else options.kind
            self.scene = make_scene(board, kind, rng)  # type: ignore[arg-type]
            if options.kind == "sort":
                self.scene.objects = sort_objects(board, self.scene.T_base_board, rng)
            self.raycasting, self.colour_of = build(self.scene)
        self.world = (
            None if options.world_file is None or self.scene is None else WorldFile(options.world_file)
        )
        if self.world is not None and self.scene is not None and not self.world.path.exists():
            write_world(self.world.path, world_of(self.scene))
        self.version = 0

    def T_base_color(self, T_base_flange: np.ndarray) -> np.ndarray:
        """(4, 4) the colour optical frame in the base frame: on the flange, or on the fixed mount."""
        if self.fixed is not None:
            return self.fixed.T_base_cam
        return T_base_flange @ self.options.T_flange_cam

    def at(self, T_base_flange: np.ndarray) -> None:
        """The eye-to-hand cell's scene with the ball where the flange pose (4, 4) puts it."""
        if self.fixed is not None:
            self.fixed.refresh()
            self.raycasting, self.colour_of = self.fixed.scene_at(T_base_flange)

    def refresh(self) -> bool:
        """Rebuild the scene when the world file changed (objects carried or set down); True then."""
        if self.world is None or self.scene is None or not self.world.poll() or self.world.state is None:
            return False
        self.scene.objects = [object_of(o) for o in self.world.state.objects]
        self.raycasting, self.colour_of = build(self.scene)
        self.version += 1
        return True

    def truth(self) -> dict[str, Any]:
        """JSON-able ground truth (base frame, metres)."""
        o = self.options
        out: dict[str, Any] = {"scene": o.scene, "seed": o.seed, "T_flange_cam": o.T_flange_cam.tolist()}
        if self.fixed is not None:
            out.update(self.fixed.truth())
            del out["T_flange_cam"]  # no camera on the flange
        elif o.scene == "ball":
            out["ball"] = {"p_base": self.ball_base.tolist(), "radius_m": o.ball_radius}
        elif self.scene is None:
            out["blob"] = {"p_base": list(map(float, self.target.p_base)), "radius": self.target.radius}
        else:
            out["kind"] = o.kind
            out["T_base_board"] = self.scene.T_base_board.tolist()
            out["objects"] = [obj.to_json() for obj in self.scene.objects]
        return out
