"""Synthetic calibration sessions: a dark blob on a white sheet fixed on the table, seen by the
flange-mounted camera from many robot poses."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation
from sofia_schemas.transforms import apply, invert

from .camera import Camera, look_at, render
from .scene import _T, DEFAULT_T_FLANGE_CAM, TABLE, _box

SHEET = (240, 240, 236)
BLOB = (25, 25, 28)
SHEET_SIZE = (0.297, 0.21)  # A4, metres
TABLE_Z = -0.05


@dataclass
class CalibrationTarget:
    """The blob: a dark disc of ``radius`` at ``p_base`` on a white sheet lying on the table."""

    p_base: np.ndarray = field(default_factory=lambda: np.array([0.45, 0.25, TABLE_Z + 0.0005]))
    radius: float = 0.015
    sheet_yaw: float = 0.3

    def build(self) -> tuple[o3d.t.geometry.RaycastingScene, object]:
        rc = o3d.t.geometry.RaycastingScene()
        table_id = rc.add_triangles(
            _box(np.array([1.6, 2.0, 0.04]), _T(np.eye(3), np.array([0.6, 0.0, TABLE_Z - 0.02])))
        )
        T_sheet = _T(
            Rotation.from_euler("z", self.sheet_yaw).as_matrix(), self.p_base - np.array([0, 0, 0.00025])
        )
        sheet_id = rc.add_triangles(_box(np.array([*SHEET_SIZE, 0.0005]), T_sheet))
        p_blob, r = self.p_base, self.radius

        def colour_of(ids: np.ndarray, points_base: np.ndarray) -> np.ndarray:
            out = np.zeros((ids.size, 3), dtype=np.uint8)
            out[ids == table_id] = TABLE
            on_sheet = ids == sheet_id
            in_blob = np.linalg.norm(points_base[:, :2] - p_blob[:2], axis=1) <= r
            out[on_sheet] = np.where(in_blob[on_sheet, None], BLOB, SHEET)
            return out

        return rc, colour_of


@dataclass
class CalibrationFrame:
    """One robot pose of a session.

    points_cam: (480, 640, 3) float32, camera optical frame, NaN where invalid.
    rgb: (480, 640, 3) uint8. T_base_flange: (4, 4). p_cam_true: (3,) blob centre, camera frame.
    blob_visible: the whole blob is inside the image.
    """

    stamp_ns: int
    points_cam: np.ndarray
    rgb: np.ndarray
    T_base_flange: np.ndarray
    p_cam_true: np.ndarray
    blob_visible: bool


@dataclass
class CalibrationSession:
    frames: list[CalibrationFrame]
    T_flange_cam: np.ndarray  # (4, 4) ground truth
    p_base_blob: np.ndarray  # (3,) ground truth
    blob_radius: float


def random_view(
    target: CalibrationTarget,
    rng: np.random.Generator,
    camera: Camera,
    distance: tuple[float, float] = (0.3, 0.55),
    max_off_axis_deg: float = 35.0,
    max_image_offset_px: float = 150.0,
) -> np.ndarray:
    """(4, 4) ``T_base_cam`` seeing the blob from above at a random direction, distance, roll and
    image position."""
    theta = np.radians(rng.uniform(0, max_off_axis_deg))
    phi = rng.uniform(-np.pi, np.pi)
    direction = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    eye = target.p_base + rng.uniform(*distance) * direction
    roll = rng.uniform(-np.pi, np.pi)
    right = np.array([np.cos(roll), np.sin(roll), 0.0])
    T = look_at(eye, target.p_base, right)
    # move the blob off the image centre by rotating the camera slightly
    du, dv = rng.uniform(-max_image_offset_px, max_image_offset_px, 2)
    R_off = Rotation.from_euler("yx", [np.arctan(du / camera.fx), -np.arctan(dv / camera.fy)]).as_matrix()
    T[:3, :3] = T[:3, :3] @ R_off
    return T


def render_calibration_frame(
    target: CalibrationTarget,
    T_base_cam: np.ndarray,
    T_flange_cam: np.ndarray,
    rng: np.random.Generator,
    camera: Camera | None = None,
    stamp_ns: int = 0,
    scene: tuple | None = None,
) -> CalibrationFrame:
    """Render the target from ``T_base_cam``."""
    camera = camera or Camera()
    rc, colour_of = scene or target.build()
    r = render(rc, colour_of, T_base_cam, camera, rng)
    p_cam = apply(invert(T_base_cam), target.p_base)
    uv = camera.project(p_cam)[0]
    r_px = camera.fx * target.radius / p_cam[2]
    visible = bool(
        p_cam[2] > 0
        and r_px <= uv[0] <= camera.width - 1 - r_px
        and r_px <= uv[1] <= camera.height - 1 - r_px
    )
    return CalibrationFrame(
        stamp_ns=stamp_ns,
        points_cam=r.points_cam,
        rgb=r.rgb,
        T_base_flange=T_base_cam @ invert(T_flange_cam),
        p_cam_true=p_cam,
        blob_visible=visible,
    )


def make_calibration_session(
    n_poses: int,
    rng: np.random.Generator,
    T_flange_cam: np.ndarray | None = None,
    target: CalibrationTarget | None = None,
    camera: Camera | None = None,
    start_ns: int = 1_700_000_000_000_000_000,
    period_ns: int = 2_000_000_000,
) -> CalibrationSession:
    """``n_poses`` frames of the blob seen from random views, all with the blob fully in view."""
    T_flange_cam = DEFAULT_T_FLANGE_CAM if T_flange_cam is None else np.asarray(T_flange_cam, float)
    target = target or CalibrationTarget()
    camera = camera or Camera()
    built = target.build()
    frames: list[CalibrationFrame] = []
    while len(frames) < n_poses:
        T_base_cam = random_view(target, rng, camera)
        f = render_calibration_frame(
            target, T_base_cam, T_flange_cam, rng, camera, start_ns + len(frames) * period_ns, built
        )
        if f.blob_visible:
            frames.append(f)
    return CalibrationSession(frames, T_flange_cam, target.p_base.copy(), target.radius)
