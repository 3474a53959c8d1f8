"""Synthetic SofIA board scenes: the board of 12 fields on a table, objects, clutter, a camera on
the Panda flange. Everything is built in the robot base frame (z up)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation
from sofia_schemas import Board
from sofia_schemas.transforms import invert

from .camera import Camera, Render, look_at, render

Shape = Literal["box", "cylinder", "sphere"]
SceneKind = Literal["one", "empty", "nonred", "two"]
SHAPES: tuple[Shape, ...] = ("box", "cylinder", "sphere")

BOARD_THICKNESS = 0.018
BOARD_MARGIN = 0.02  # wooden rim around the fields, metres
WOOD = (194, 154, 108)
RED = (200, 30, 35)
WHITE = (235, 233, 228)
TABLE = (128, 128, 128)
ROBOT = (230, 230, 225)
FINGER = (30, 30, 30)
OBJECT_COLOURS = ((30, 80, 200), (40, 160, 60), (230, 200, 40), (150, 60, 170), (20, 150, 160))


def _T(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


# Flange -> camera optical frame of SofIA's D435 (the synthetic ground truth): optical axis along
# the flange z axis tilted 8 degrees, camera 6.5 cm off the flange axis and 4.5 cm below it.
DEFAULT_T_FLANGE_CAM = _T(
    Rotation.from_euler("zx", [90.0, -8.0], degrees=True).as_matrix(), np.array([0.065, 0.0, 0.045])
)


@dataclass
class ObjectTruth:
    """Ground truth of one object (base frame, metres, radians)."""

    shape: Shape
    center: np.ndarray  # (3,) centre of the bounding box
    extents: np.ndarray  # (3,) length, width, height in the object's own axes
    yaw: float  # about the base z axis
    field: tuple[int, int]
    allowed: bool
    T_base_obj: np.ndarray  # (4, 4)
    colour: tuple[int, int, int]

    def to_json(self) -> dict[str, object]:
        return {
            "shape": self.shape,
            "center": self.center.tolist(),
            "extents": self.extents.tolist(),
            "yaw": self.yaw,
            "field": list(self.field),
            "allowed": self.allowed,
            "T_base_obj": self.T_base_obj.tolist(),
        }


@dataclass
class Scene:
    """Geometry of one scene: the true board pose and the objects on it."""

    board: Board  # configured board (what the detector is told)
    T_base_board: np.ndarray  # (4, 4) true board pose (surface centre), differs from the configured one
    objects: list[ObjectTruth] = field(default_factory=list)
    clutter: bool = True


def perturb_board(
    board: Board, rng: np.random.Generator, max_offset: float = 0.03, max_tilt_deg: float = 3.0
) -> np.ndarray:
    """(4, 4) true board pose: the configured one moved by up to ``max_offset`` metres (of which at
    most 1.5 cm vertically) and tilted by up to ``max_tilt_deg`` about a random horizontal axis,
    with up to 3 degrees of yaw."""
    while True:
        d = rng.uniform(-max_offset, max_offset, 3)
        d[2] = np.clip(d[2], -0.015, 0.015)
        if np.linalg.norm(d) <= max_offset:
            break
    axis = np.array([*rng.normal(size=2), 0.0])
    axis /= np.linalg.norm(axis)
    tilt = Rotation.from_rotvec(axis * np.radians(rng.uniform(0, max_tilt_deg)))
    yaw = Rotation.from_euler("z", rng.uniform(-3, 3), degrees=True)
    T = board.T_base_board.copy()
    T[:3, :3] = (tilt * yaw).as_matrix() @ T[:3, :3]
    T[:3, 3] += d
    return T


def random_object(
    board: Board,
    T_base_board: np.ndarray,
    fld: tuple[int, int],
    rng: np.random.Generator,
    shape: Shape | None = None,
) -> ObjectTruth:
    """An object of 3 to 10 cm with random yaw lying inside field ``fld`` of the true board."""
    shape = shape or SHAPES[rng.integers(len(SHAPES))]
    if shape == "box":
        ext = rng.uniform(0.03, 0.10, 3)
    elif shape == "cylinder":
        d, h = rng.uniform(0.03, 0.10, 2)
        ext = np.array([d, d, h])
    else:
        ext = np.full(3, rng.uniform(0.03, 0.10))
    yaw_board = rng.uniform(-np.pi, np.pi)
    r_fp = 0.5 * np.hypot(ext[0], ext[1]) if shape == "box" else 0.5 * ext[0]
    slack = np.maximum(np.array(board.field_size) / 2 - r_fp - 0.005, 0.0)
    xy = board.field_centers_board()[fld] + rng.uniform(-slack, slack)
    T_board_obj = _T(Rotation.from_euler("z", yaw_board).as_matrix(), np.array([xy[0], xy[1], ext[2] / 2]))
    T_base_obj = T_base_board @ T_board_obj
    x_axis = T_base_obj[:3, 0]
    return ObjectTruth(
        shape=shape,
        center=T_base_obj[:3, 3].copy(),
        extents=ext,
        yaw=float(np.arctan2(x_axis[1], x_axis[0])),
        field=fld,
        allowed=board.is_allowed(*fld),
        T_base_obj=T_base_obj,
        colour=OBJECT_COLOURS[rng.integers(len(OBJECT_COLOURS))],
    )


def make_scene(
    board: Board,
    kind: SceneKind,
    rng: np.random.Generator,
    shape: Shape | None = None,
    fld: tuple[int, int] | None = None,
    perturb: bool = True,
) -> Scene:
    """A scene of ``kind``: one object on a red field, an empty board, one object on a non-red
    field, or two objects on two fields (at least one red)."""
    T_base_board = perturb_board(board, rng) if perturb else board.T_base_board
    red = [tuple(a) for a in board.allowed]
    other = [(r, c) for r in range(board.rows) for c in range(board.cols) if (r, c) not in red]
    scene = Scene(board=board, T_base_board=T_base_board)
    if kind == "one":
        fields = [fld or red[rng.integers(len(red))]]
    elif kind == "nonred":
        fields = [fld or other[rng.integers(len(other))]]
    elif kind == "two":
        a = red[rng.integers(len(red))]
        rest = [f for f in red + other if f != a]
        fields = [a, rest[rng.integers(len(rest))]]
    elif kind == "empty":
        fields = []
    else:
        raise ValueError(f"scene kind {kind!r} is not one of one, empty, nonred, two")
    scene.objects = [random_object(board, T_base_board, f, rng, shape) for f in fields]  # type: ignore[arg-type]
    return scene


def _tmesh(mesh: o3d.geometry.TriangleMesh, T: np.ndarray) -> o3d.t.geometry.TriangleMesh:
    mesh.transform(T)
    return o3d.t.geometry.TriangleMesh.from_legacy(mesh)


def _box(size: np.ndarray, T: np.ndarray) -> o3d.t.geometry.TriangleMesh:
    m = o3d.geometry.TriangleMesh.create_box(
        width=float(size[0]), height=float(size[1]), depth=float(size[2])
    )
    m.translate(-np.asarray(size, float) / 2)
    return _tmesh(m, T)


def object_mesh(obj: ObjectTruth) -> o3d.t.geometry.TriangleMesh:
    l, _w, h = map(float, obj.extents)
    if obj.shape == "box":
        return _box(obj.extents, obj.T_base_obj)
    if obj.shape == "cylinder":
        return _tmesh(
            o3d.geometry.TriangleMesh.create_cylinder(l / 2, h, resolution=96, split=1), obj.T_base_obj
        )
    return _tmesh(o3d.geometry.TriangleMesh.create_sphere(l / 2, resolution=48), obj.T_base_obj)


def build(scene: Scene, T_base_flange: np.ndarray | None = None):  # type: ignore[no-untyped-def]
    """Open3D ray-casting scene and the colour function of ``scene`` (see :func:`camera.render`)."""
    rc = o3d.t.geometry.RaycastingScene()
    colours: dict[int, tuple[int, int, int]] = {}
    board = scene.board
    ex, ey = board.extent
    board_size = np.array([ex + 2 * BOARD_MARGIN, ey + 2 * BOARD_MARGIN, BOARD_THICKNESS])
    board_id = rc.add_triangles(
        _box(board_size, scene.T_base_board @ _T(np.eye(3), np.array([0, 0, -BOARD_THICKNESS / 2])))
    )
    table_z = board.surface_z - BOARD_THICKNESS - 0.03
    colours[
        rc.add_triangles(
            _box(np.array([1.6, 2.0, 0.04]), _T(np.eye(3), np.array([0.6, 0.0, table_z - 0.02])))
        )
    ] = TABLE
    if scene.clutter:
        colours[
            rc.add_triangles(
                _box(np.array([0.2, 0.2, 0.35]), _T(np.eye(3), np.array([0.0, 0.0, table_z + 0.175])))
            )
        ] = ROBOT
        clutter_T = _T(
            Rotation.from_euler("z", 0.4).as_matrix(),
            np.array([board.center[0] + 0.05, board.center[1] + ey / 2 + 0.09, table_z + 0.06]),
        )
        colours[rc.add_triangles(_box(np.array([0.08, 0.06, 0.12]), clutter_T))] = (90, 60, 40)
    if T_base_flange is not None:  # the Fin-Ray fingers in front of the camera
        for sx in (-1.0, 1.0):
            T_flange_finger = _T(np.eye(3), np.array([-0.03, sx * 0.035, 0.13]))
            colours[
                rc.add_triangles(_box(np.array([0.02, 0.012, 0.07]), T_base_flange @ T_flange_finger))
            ] = FINGER
    for obj in scene.objects:
        colours[rc.add_triangles(object_mesh(obj))] = obj.colour
    T_board_base = invert(scene.T_base_board)
    red = np.array([board.is_allowed(r, c) for r in range(board.rows) for c in range(board.cols)])

    def colour_of(ids: np.ndarray, points_base: np.ndarray) -> np.ndarray:
        out = np.zeros((ids.size, 3), dtype=np.uint8)
        for gid, col in colours.items():
            out[ids == gid] = col
        on_board = ids == board_id
        p_board = points_base[on_board] @ T_board_base[:3, :3].T + T_board_base[:3, 3]
        rc_idx = board.field_of_board_xy(p_board[:, :2])
        inside = rc_idx[:, 0] >= 0
        top = p_board[:, 2] > -1e-3
        flat = rc_idx[:, 0] * board.cols + rc_idx[:, 1]
        field_colour = np.where(
            (inside & top)[:, None], np.where(red[np.clip(flat, 0, None)][:, None], RED, WHITE), WOOD
        )
        out[on_board] = field_colour.astype(np.uint8)
        return out

    return rc, colour_of


def camera_pose_above(
    scene: Scene,
    rng: np.random.Generator,
    height: tuple[float, float] = (0.72, 0.80),
    jitter: float = 0.015,
    tilt_deg: float = 2.0,
) -> np.ndarray:
    """(4, 4) ``T_base_cam`` above the board centre looking down, image x along the board's y axis."""
    c = scene.T_base_board[:3, 3]
    eye = c + np.array([*rng.uniform(-jitter, jitter, 2), rng.uniform(*height)])
    tilt = np.tan(np.radians(rng.uniform(0, tilt_deg))) * (eye[2] - c[2])
    ang = rng.uniform(-np.pi, np.pi)
    target = c + np.array([tilt * np.cos(ang), tilt * np.sin(ang), 0.0])
    right = scene.T_base_board[:3, 1] + rng.normal(0, 0.05, 3)
    return look_at(eye, target, right)


@dataclass
class SceneFrame:
    """A rendered board scene with its poses and truth."""

    scene: Scene
    render: Render
    T_base_cam: np.ndarray
    T_base_flange: np.ndarray
    T_flange_cam: np.ndarray
    points_base: np.ndarray  # (H, W, 3) float32, base frame, NaN where invalid


def render_scene(
    scene: Scene,
    rng: np.random.Generator,
    camera: Camera | None = None,
    T_flange_cam: np.ndarray = DEFAULT_T_FLANGE_CAM,
    T_base_cam: np.ndarray | None = None,
) -> SceneFrame:
    """Render ``scene`` from a camera above the board (or at ``T_base_cam``)."""
    camera = camera or Camera()
    if T_base_cam is None:
        T_base_cam = camera_pose_above(scene, rng)
    T_base_flange = T_base_cam @ invert(T_flange_cam)
    rc, colour_of = build(scene, T_base_flange)
    r = render(rc, colour_of, T_base_cam, camera, rng)
    p = r.points_cam.astype(np.float64) @ T_base_cam[:3, :3].T + T_base_cam[:3, 3]
    return SceneFrame(scene, r, T_base_cam, T_base_flange, T_flange_cam, p.astype(np.float32))
