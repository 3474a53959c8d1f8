"""What a real D435 makes of a scene: active stereo with a second imager 50 mm to the right.

From the depth camera's physics, per pixel of an image aligned with the left imager:

- **occlusion shadows**: a point is measured only when the right imager sees it too, so surfaces
  hidden from it (beside the left edge of every raised object) and the band on the image's left
  that lies outside the right imager's view have no depth;
- **disparity quantisation and noise**: depth is ``fx b / d`` with the disparity ``d`` known to
  a fraction of a pixel (sub-pixel noise, 1/32 px steps), then written in 1 mm units;
- **flying pixels**: at depth discontinuities the matching window straddles foreground and
  background, giving depths anywhere between the two;
- **dark, low-reflectance surfaces** (black objects, the fingers) and surfaces seen at grazing
  angles return no pattern: blobs of missing depth;
- colour is seen wherever the surface is, with Lambertian shading and exposure changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy import ndimage, special

from .camera import INVALID_ID, Camera

# colour-aligned depth intrinsics of the three D435 modes (fx = fy, principal point at the middle)
MODES: dict[tuple[int, int], float] = {(640, 480): 615.0, (848, 480): 610.0, (1280, 720): 920.0}


def d435_camera(width: int = 640, height: int = 480) -> Camera:
    """The :class:`Camera` of a D435 mode (640x480, 848x480 or 1280x720)."""
    if (width, height) not in MODES:
        raise ValueError(f"D435 mode {width}x{height} is not one of {sorted(MODES)}")
    f = MODES[(width, height)]
    return Camera(width=width, height=height, fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2)


@dataclass(frozen=True)
class StereoModel:
    """Sensor effects (metres, pixels).

    baseline: distance of the right imager along the image x axis. subpixel: disparity noise (px
    RMS). disparity_step: disparity resolution (px). depth_unit: depth quantum. flying_jump:
    depth step within a 3x3 window that makes flying pixels; flying_rate: the fraction of such
    pixels that get a mixed depth. dark_albedo: surfaces darker than this (0-1 luminance) lose
    depth, up to ``max_hole_rate`` of them, in blobs of ``hole_blob`` px. grazing_cos: surfaces
    seen at an angle whose cosine is below this return nothing. drop_rate: random dropouts.
    """

    baseline: float = 0.050
    subpixel: float = 0.08
    disparity_step: float = 1.0 / 32.0
    depth_unit: float = 0.001
    flying_jump: float = 0.02
    flying_rate: float = 0.6
    dark_albedo: float = 0.22
    max_hole_rate: float = 0.6
    hole_blob: float = 2.5
    grazing_cos: float = 0.1
    drop_rate: float = 0.003


@dataclass
class Cast:
    """One ray cast: depth (H, W) along the optical axis (inf: no hit), ids (H, W) int64 (-1: no
    hit), normals (H, W, 3) base frame, points_base (H, W, 3) noise-free hits."""

    depth: np.ndarray
    ids: np.ndarray
    normals: np.ndarray
    points_base: np.ndarray


def cast_camera(rc: o3d.t.geometry.RaycastingScene, T_base_cam: np.ndarray, camera: Camera) -> Cast:
    """Ray-cast ``rc`` (base frame) from a camera at ``T_base_cam`` (4, 4)."""
    d_base = camera.ray_directions_cam() @ T_base_cam[:3, :3].T  # z = 1 in the camera frame
    origins = np.broadcast_to(T_base_cam[:3, 3], d_base.shape)
    rays = np.concatenate([origins, d_base], axis=-1).astype(np.float32)
    hit = rc.cast_rays(o3d.core.Tensor.from_numpy(rays))
    ids = hit["geometry_ids"].numpy().astype(np.int64)
    ids[ids == INVALID_ID] = -1
    depth = hit["t_hit"].numpy().astype(np.float64)
    depth[ids < 0] = np.inf
    points = T_base_cam[:3, 3] + d_base * np.where(ids >= 0, depth, 0.0)[..., None]
    return Cast(depth, ids, hit["primitive_normals"].numpy().astype(np.float64), points)


def seen_by_right_imager(
    rc: o3d.t.geometry.RaycastingScene, c: Cast, T_base_cam: np.ndarray, camera: Camera, baseline: float
) -> np.ndarray:
    """(H, W) bool: the hit is inside the right imager's view and not hidden from it."""
    p_cam = (c.points_base - T_base_cam[:3, 3]) @ T_base_cam[:3, :3]
    with np.errstate(invalid="ignore", divide="ignore"):
        u_right = camera.fx * (p_cam[..., 0] - baseline) / p_cam[..., 2] + camera.cx
    in_view = (c.ids >= 0) & (u_right >= 0)
    origin = T_base_cam[:3, 3] + baseline * T_base_cam[:3, 0]
    d = c.points_base - origin
    rays = np.concatenate([np.broadcast_to(origin, d.shape), d], axis=-1).astype(np.float32)
    t = rc.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy().astype(np.float64)
    slack = 0.002 / np.maximum(np.linalg.norm(d, axis=-1), 1e-6)
    return in_view & (t >= 1.0 - slack)


def _blobs(shape: tuple[int, int], sigma: float, rng: np.random.Generator) -> np.ndarray:
    """(H, W) spatially correlated values, uniform on [0, 1]."""
    f = ndimage.gaussian_filter(rng.standard_normal(shape), sigma)
    return special.ndtr(f / max(float(f.std()), 1e-9))  # type: ignore[no-any-return]


def stereo_depth(
    rc: o3d.t.geometry.RaycastingScene,
    c: Cast,
    albedo: np.ndarray,
    T_base_cam: np.ndarray,
    camera: Camera,
    model: StereoModel,
    rng: np.random.Generator,
) -> np.ndarray:
    """(H, W) depth (metres, NaN where the sensor gives none) of the cast ``c``.

    albedo: (H, W) luminance of the surface hit, 0-1.
    """
    valid = seen_by_right_imager(rc, c, T_base_cam, camera, model.baseline)
    d_base = camera.ray_directions_cam() @ T_base_cam[:3, :3].T
    cos = np.abs(np.einsum("hwk,hwk->hw", c.normals, d_base)) / np.linalg.norm(d_base, axis=-1)
    valid &= cos >= model.grazing_cos
    hole_p = np.clip(1.6 * (model.dark_albedo - albedo) / model.dark_albedo, 0.0, model.max_hole_rate)
    valid &= _blobs(c.depth.shape, model.hole_blob, rng) >= hole_p
    valid &= rng.random(c.depth.shape) >= model.drop_rate
    far = np.where(c.ids >= 0, c.depth, 10.0)
    lo = ndimage.minimum_filter(far, size=3)
    hi = ndimage.maximum_filter(far, size=3)
    mixed = (hi - lo > model.flying_jump) & (rng.random(far.shape) < model.flying_rate)
    z = np.where(mixed, lo + rng.random(far.shape) * (hi - lo), far)
    fb = camera.fx * model.baseline
    disparity = fb / z + rng.standard_normal(z.shape) * model.subpixel
    disparity = np.round(disparity / model.disparity_step) * model.disparity_step
    with np.errstate(divide="ignore"):
        z = np.round(fb / disparity / model.depth_unit) * model.depth_unit
    valid &= (disparity > 0) & (z >= camera.min_depth) & (z <= camera.max_depth)
    return np.where(valid, z, np.nan)


def shade(
    paint: np.ndarray, c: Cast, T_base_cam: np.ndarray, camera: Camera, gain: float, rng: np.random.Generator
) -> np.ndarray:
    """(H, W, 3) uint8 colour image: ``paint`` (H, W, 3) 0-255 under a light at the camera and one
    overhead, times the exposure ``gain``, with sensor noise; black where nothing is hit."""
    d_base = camera.ray_directions_cam() @ T_base_cam[:3, :3].T
    cos_view = np.abs(np.einsum("hwk,hwk->hw", c.normals, d_base)) / np.linalg.norm(d_base, axis=-1)
    light = 0.35 + 0.4 * cos_view + 0.25 * np.abs(c.normals[..., 2])
    rgb = paint * (gain * light)[..., None] + rng.normal(0.0, 3.0, paint.shape)
    rgb[c.ids < 0] = 0
    return np.clip(rgb, 0, 255).astype(np.uint8)
