"""The eye-to-hand cell the simulated D435 renders: the camera on a fixed mount looking at the
workspace, a coloured ball on the flange, the table below (``--sim-scene eye-to-hand``).

The mount and the ball live in the shared world file (:mod:`sofia_schemas.sim_world`) when there
is one, so every process of the cell reads the same truth; the ray-casting scene is built again
for each flange pose (the ball moves with it). Base frame, metres.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import open3d as o3d
from sofia_replay.synth.calibration import TABLE_Z
from sofia_replay.synth.camera import look_at
from sofia_replay.synth.scene import TABLE, _box
from sofia_schemas.sim_world import FlangeBall, WorldFile, WorldState, write_world
from sofia_schemas.transforms import as_transforms

# the fixed camera: 0.75 m in front of the robot and to its right, looking back at the workspace
DEFAULT_T_BASE_CAM = look_at(
    np.array([1.05, -0.35, 0.55]), np.array([0.4, 0.0, 0.42]), np.array([0.4, 1.0, 0.0])
)
DEFAULT_BALL_FLANGE = (0.0, 0.0, 0.1)  # the ball's centre 10 cm out along the flange z axis
DEFAULT_BALL_RADIUS = 0.025
BALL_RESOLUTION = 96  # triangle-mesh sphere: faceting error below 5 um at these radii
BALL_COLOUR = FlangeBall.model_fields["colour"].default  # orange


def eye_to_hand_state(
    T_base_cam: np.ndarray, p_flange: tuple[float, float, float], radius_m: float
) -> WorldState:
    """The world of the eye-to-hand cell: table top at ``TABLE_Z``, the mount and the ball."""
    T_base_table = np.eye(4)
    T_base_table[2, 3] = TABLE_Z
    return WorldState(
        T_base_board=T_base_table.tolist(), T_base_cam=as_transforms(T_base_cam, "T_base_cam", tol=1e-4).tolist(),
        flange_ball=FlangeBall(p_flange=p_flange, radius_m=radius_m),
    )  # fmt: skip


class FixedCameraCell:
    """The mount and the ball of a :class:`WorldState` (re-read from the world file when it
    changes), and the ray-casting scene at a flange pose (:meth:`scene_at`)."""

    def __init__(self, state: WorldState, world_file: WorldFile | None = None) -> None:
        if world_file is not None and not world_file.path.exists():
            write_world(world_file.path, state)
        self.file = world_file
        self.state = state
        self.refresh()

    def refresh(self) -> bool:
        """Take the world file's mount and ball when it changed; True then."""
        if self.file is None or not self.file.poll() or self.file.state is None:
            return False
        if self.file.state.T_base_cam is None or self.file.state.flange_ball is None:
            return False  # a world without a mount or ball: keep the cell's own
        self.state = self.file.state
        return True

    @property
    def T_base_cam(self) -> np.ndarray:
        """(4, 4) the fixed camera's colour optical frame, base frame."""
        assert self.state.T_base_cam is not None
        return np.array(self.state.T_base_cam, dtype=np.float64)

    @property
    def ball(self) -> FlangeBall:
        assert self.state.flange_ball is not None
        return self.state.flange_ball

    def scene_at(self, T_base_flange: np.ndarray) -> tuple[o3d.t.geometry.RaycastingScene, Any]:
        """The ray-casting scene (table and ball) with the flange at ``T_base_flange`` (4, 4), and
        the colour of each hit (``colour_of(ids, points_base)``)."""
        ball = self.ball
        return table_and_ball(ball.centre_base(T_base_flange), ball.radius_m, ball.colour)

    def truth(self) -> dict[str, Any]:
        """JSON-able truth: ``T_base_cam`` and the ball (flange frame, metres)."""
        return {"T_base_cam": self.T_base_cam.tolist(), "ball": self.ball.model_dump(mode="json")}


def table_and_ball(
    p_ball_base: np.ndarray, radius_m: float, colour: tuple[int, int, int] = BALL_COLOUR
) -> tuple[o3d.t.geometry.RaycastingScene, Any]:
    """The ray-casting scene of the table (top at ``TABLE_Z``) and a ball of ``radius_m`` centred
    at p_ball_base (3,), base frame, metres; and the colour of each hit (``colour_of(ids,
    points_base)``). The ball may lie on the table (eye-in-hand) or ride on the flange."""
    rc = o3d.t.geometry.RaycastingScene()
    table_id = rc.add_triangles(
        _box(
            np.array([1.6, 2.0, 0.04]),
            np.array([[1, 0, 0, 0.6], [0, 1, 0, 0], [0, 0, 1, TABLE_Z - 0.02], [0, 0, 0, 1.0]]),
        )
    )
    mesh = o3d.geometry.TriangleMesh.create_sphere(radius_m, resolution=BALL_RESOLUTION)
    mesh.translate(np.asarray(p_ball_base, dtype=np.float64))
    ball_id = rc.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    rgb = np.array(colour, dtype=np.uint8)

    def colour_of(ids: np.ndarray, points_base: np.ndarray) -> np.ndarray:
        out = np.zeros((ids.size, 3), dtype=np.uint8)
        out[ids == table_id] = TABLE
        out[ids == ball_id] = rgb
        return out

    return rc, colour_of
