"""Board scenes as a real D435 on SofIA's flange sees them (see :mod:`.d435`), by category.

Categories: one object of each kind of :data:`.objects.KINDS` (``puck`` is the low one,
``bottle`` the tall one), ``dark`` (a black object), ``three-colour`` (a yellow, a green and a
blue object and a distractor), ``edge-cut`` (an object cut by the image border), ``occluded``
(an object partly behind SofIA's fingers), ``empty`` and ``other-board`` (a 2 x 3 board of
18 cm fields). The real board is off its configured pose by up to 4 cm and 4 degrees; the fingers
are in view at the image bottom in two scenes of three (always in ``empty`` and ``occluded``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
from sofia_schemas import Board

from .camera import Camera
from .d435 import StereoModel, cast_camera, d435_camera, shade, stereo_depth
from .objects import KINDS, PAINT, RealObject, object_tmesh, place_object
from .scene import FINGER, Scene, build, camera_pose_above, perturb_board

CATEGORIES = (*KINDS, "dark", "three-colour", "edge-cut", "occluded", "empty", "other-board")
OTHER_BOARD = Board(
    rows=2, cols=3, field_size=(0.18, 0.18), allowed=((0, 0), (0, 2), (1, 1)), center=(0.5, 0.02)
)
FINGER_DEPTH = 0.18  # fingers' distance along the optical axis, metres
FINGER_TOP = 0.05  # image-down offset of the fingertips at that distance, metres
LIGHT_COLOURS = tuple(c for c in PAINT if c != "black")
BENCH_RESOLUTIONS = ((640, 480), (848, 480), (1280, 720))  # the k-th scene of a category: k % 3
BENCH_SEED = 50_000  # scene k of category i is drawn from seed BENCH_SEED + 1000 i + k


@dataclass
class RealFrame:
    """A rendered realistic scene.

    points_base: (H, W, 3) float32, base frame, metres, NaN where the sensor gives no depth.
    depth_mm: (H, W) uint16 depth in millimetres (0: none), as the camera streams it. rgb:
    (H, W, 3) uint8 aligned colour. visibility[i]: fraction of object i's silhouette in the image
    and not behind the fingers; in_image[i]: fraction inside the image borders; depth_valid[i]:
    fraction of its visible pixels with depth.
    """

    category: str
    board: Board
    T_base_board: np.ndarray
    objects: list[RealObject]
    camera: Camera
    T_base_cam: np.ndarray
    points_base: np.ndarray
    depth_mm: np.ndarray
    rgb: np.ndarray
    visibility: list[float] = field(default_factory=list)
    in_image: list[float] = field(default_factory=list)
    depth_valid: list[float] = field(default_factory=list)


def _box_t(size: tuple[float, float, float], T: np.ndarray) -> o3d.t.geometry.TriangleMesh:
    m = o3d.geometry.TriangleMesh.create_box(*size)
    m.translate(-np.asarray(size) / 2)
    m.transform(T)
    return o3d.t.geometry.TriangleMesh.from_legacy(m)


def _assemble(
    board: Board,
    T_base_board: np.ndarray,
    objects: list[RealObject],
    T_base_cam: np.ndarray,
    finger_x: float | None,
):  # type: ignore[no-untyped-def]
    rc, colour_of = build(Scene(board=board, T_base_board=T_base_board), None)
    paints: dict[int, tuple[int, int, int]] = {}
    if finger_x is not None:
        for sx in (-1.0, 1.0):
            T_cam_finger = np.eye(4)
            T_cam_finger[:3, 3] = (sx * finger_x, FINGER_TOP + 0.06, FINGER_DEPTH)
            paints[rc.add_triangles(_box_t((0.022, 0.12, 0.02), T_base_cam @ T_cam_finger))] = FINGER
    ids = []
    for obj in objects:
        ids.append(rc.add_triangles(object_tmesh(obj)))
        paints[ids[-1]] = obj.rgb

    def paint_of(gids: np.ndarray, points_base: np.ndarray) -> np.ndarray:
        out = colour_of(gids, points_base)
        for gid, col in paints.items():
            out[gids == gid] = col
        return out

    return rc, paint_of, ids


def render_real(
    board: Board,
    T_base_board: np.ndarray,
    objects: list[RealObject],
    T_base_cam: np.ndarray,
    camera: Camera,
    rng: np.random.Generator,
    finger_x: float | None = 0.045,
    model: StereoModel | None = None,
    category: str = "",
) -> RealFrame:
    """Render ``objects`` on the real board (``T_base_board`` (4, 4)) from ``T_base_cam`` (4, 4).

    finger_x: half the spacing of the fingers across the image (camera frame, metres), None
    without fingers.
    """
    model = model or StereoModel()
    rc, paint_of, ids = _assemble(board, T_base_board, objects, T_base_cam, finger_x)
    c = cast_camera(rc, T_base_cam, camera)
    paint = np.zeros((*c.ids.shape, 3))
    hit = c.ids >= 0
    paint[hit] = paint_of(c.ids[hit], c.points_base[hit])
    albedo = (paint @ np.array([0.2126, 0.7152, 0.0722])) / 255.0
    depth = stereo_depth(rc, c, albedo, T_base_cam, camera, model, rng)
    rgb = shade(paint, c, T_base_cam, camera, float(rng.uniform(0.75, 1.15)), rng)
    points_cam = camera.ray_directions_cam() * depth[..., None]
    points_base = (points_cam @ T_base_cam[:3, :3].T + T_base_cam[:3, 3]).astype(np.float32)
    depth_mm = np.where(np.isfinite(depth), np.round(depth * 1e3), 0).astype(np.uint16)
    frame = RealFrame(category, board, T_base_board, objects, camera, T_base_cam, points_base, depth_mm, rgb)
    if objects:
        _visibility(frame, c.ids, ids, np.isfinite(depth))
    return frame


def _visibility(frame: RealFrame, ids: np.ndarray, gids: list[int], valid: np.ndarray) -> None:
    """Fill the visibility fields of ``frame`` from a half-resolution render of a wider view
    without fingers."""
    cam = frame.camera
    m = cam.width // 3
    wide = Camera(
        width=(cam.width + 2 * m) // 2, height=(cam.height + 2 * m) // 2, fx=cam.fx / 2, fy=cam.fy / 2,
        cx=(cam.cx + m) / 2, cy=(cam.cy + m) / 2,
    )  # fmt: skip
    rc, _, wide_gids = _assemble(frame.board, frame.T_base_board, frame.objects, frame.T_base_cam, None)
    w_ids = cast_camera(rc, frame.T_base_cam, wide).ids
    u = (np.arange(wide.width) - wide.cx) * 2 + cam.cx
    v = (np.arange(wide.height) - wide.cy) * 2 + cam.cy
    inner = ((v >= -0.5) & (v <= cam.height - 0.5))[:, None] & ((u >= -0.5) & (u <= cam.width - 0.5))[None, :]
    for gid, wgid in zip(gids, wide_gids, strict=True):
        full = max(int(np.count_nonzero(w_ids == wgid)), 1)
        inside = int(np.count_nonzero((w_ids == wgid) & inner))
        seen = ids == gid
        n_seen = int(np.count_nonzero(seen))
        frame.in_image.append(min(inside / full, 1.0))
        frame.visibility.append(min(n_seen / 4 / full, 1.0))
        frame.depth_valid.append(float(np.count_nonzero(seen & valid)) / max(n_seen, 1))


def aim(T_base_cam: np.ndarray, p_base: np.ndarray, uv: tuple[float, float], camera: Camera) -> np.ndarray:
    """(4, 4) the camera moved parallel to its image plane so that ``p_base`` (3,) projects at
    pixel ``uv``."""
    p_cam = T_base_cam[:3, :3].T @ (p_base - T_base_cam[:3, 3])
    d = np.array(
        [
            p_cam[0] - (uv[0] - camera.cx) * p_cam[2] / camera.fx,
            p_cam[1] - (uv[1] - camera.cy) * p_cam[2] / camera.fy,
            0,
        ]
    )
    T = T_base_cam.copy()
    T[:3, 3] += T_base_cam[:3, :3] @ d
    return T


def _fields(board: Board, n: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    cells = [(r, c) for r in range(board.rows) for c in range(board.cols)]
    return [cells[i] for i in rng.choice(len(cells), size=n, replace=False)]


def make_real_frame(
    board: Board, category: str, rng: np.random.Generator, resolution: tuple[int, int] = (640, 480)
) -> RealFrame:
    """A random scene of ``category`` (see :data:`CATEGORIES`) rendered at ``resolution``."""
    if category not in CATEGORIES:
        raise ValueError(f"scene category {category!r} is not one of {CATEGORIES}")
    camera = d435_camera(*resolution)
    board = OTHER_BOARD if category == "other-board" else board
    T_base_board = perturb_board(board, rng, max_offset=0.04, max_tilt_deg=4.0)
    colour = LIGHT_COLOURS[rng.integers(len(LIGHT_COLOURS))]
    fingers = category in ("empty", "occluded") or rng.random() < 2 / 3
    if category in KINDS:
        specs = [(category, colour)]
    elif category == "dark":
        specs = [(("box", "cylinder", "sphere", "puck", "cone")[rng.integers(5)], "black")]
    elif category == "three-colour":
        distractor = ("white", "grey", "purple", "orange", "red")[rng.integers(5)]
        specs = [(KINDS[rng.integers(4)], c) for c in ("yellow", "green", "blue", distractor)]
    elif category in ("edge-cut", "occluded", "other-board"):
        specs = [(("box", "cylinder", "sphere", "cone", "bottle", "lying")[rng.integers(6)], colour)]
    else:
        specs = []
    flds = _fields(board, len(specs), rng)
    objects = [place_object(board, T_base_board, k, f, c, rng) for (k, c), f in zip(specs, flds, strict=True)]
    T_base_cam = camera_pose_above(
        Scene(board=board, T_base_board=T_base_board), rng, (0.62, 0.85), tilt_deg=5.0
    )
    finger_x = float(rng.uniform(0.035, 0.06)) if fingers else None
    if (category in ("edge-cut", "occluded") and finger_x is not None) or category == "edge-cut":
        obj = objects[0]
        depth = float((T_base_cam[:3, :3].T @ (obj.center - T_base_cam[:3, 3]))[2])
        r_px = camera.fx * 0.5 * float(np.hypot(*obj.extents[:2])) / depth
        W, H = camera.width, camera.height
        if category == "edge-cut":
            dist = float(rng.uniform(-0.5, 1.0)) * r_px
            side = int(rng.integers(4))
            uv = [
                (-0.5 + dist, H / 2),
                (W - 0.5 - dist, H / 2),
                (W / 2, -0.5 + dist),
                (W / 2, H - 0.5 - dist),
            ][side]
            uv = (
                uv[0] + rng.uniform(-0.2, 0.2) * W * (side > 1),
                uv[1] + rng.uniform(-0.2, 0.2) * H * (side < 2),
            )
        else:
            sx = 1.0 if rng.random() < 0.5 else -1.0
            assert finger_x is not None
            v_top = camera.cy + camera.fy * FINGER_TOP / FINGER_DEPTH
            uv = (
                camera.cx + sx * camera.fx * finger_x / FINGER_DEPTH,
                v_top - float(rng.uniform(0.0, 1.0)) * r_px,
            )
        T_base_cam = aim(T_base_cam, obj.center, uv, camera)
    return render_real(board, T_base_board, objects, T_base_cam, camera, rng, finger_x, category=category)


def bench_frame(board: Board, category: str, k: int) -> RealFrame:
    """The k-th scene of ``category`` of the realistic detector benchmark (its seed and
    resolution), as ``bench/bench_detector_real.py`` renders it as ``<category>-<k:03d>``."""
    seed = BENCH_SEED + 1000 * CATEGORIES.index(category) + k
    return make_real_frame(board, category, np.random.default_rng(seed), BENCH_RESOLUTIONS[k % 3])
