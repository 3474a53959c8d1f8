"""A D435-like depth camera: pinhole intrinsics, ray casting with Open3D, depth noise, dropouts.

Frames: the camera optical frame has z forward, x right, y down (ROS ``*_optical_frame``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

INVALID_ID = o3d.t.geometry.RaycastingScene.INVALID_ID


@dataclass(frozen=True)
class Camera:
    """Intel RealSense D435 depth stream at 640x480, aligned to colour.

    ``noise_at_half_m``: depth noise standard deviation at 0.5 m, metres; it grows with the square
    of the depth. ``drop_rate``: fraction of valid pixels lost at random. ``edge_jump``: depth step
    between neighbouring pixels (metres) above which both are invalid (flying-pixel removal).
    """

    width: int = 640
    height: int = 480
    fx: float = 615.0
    fy: float = 615.0
    cx: float = 319.5
    cy: float = 239.5
    min_depth: float = 0.17
    max_depth: float = 3.0
    noise_at_half_m: float = 0.001
    drop_rate: float = 0.01
    edge_jump: float = 0.015

    @property
    def K(self) -> np.ndarray:
        """(3, 3) intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def depth_sigma(self, depth: np.ndarray) -> np.ndarray:
        """Depth noise standard deviation (metres) at ``depth`` (metres)."""
        return self.noise_at_half_m * (np.asarray(depth) / 0.5) ** 2

    def ray_directions_cam(self) -> np.ndarray:
        """(H, W, 3) ray directions in the camera optical frame, scaled so that z = 1."""
        u, v = np.meshgrid(np.arange(self.width), np.arange(self.height))
        return np.stack([(u - self.cx) / self.fx, (v - self.cy) / self.fy, np.ones(u.shape)], axis=-1)

    def project(self, p_cam: np.ndarray) -> np.ndarray:
        """(n, 2) pixel coordinates (u, v) of camera-frame points (n, 3)."""
        p_cam = np.atleast_2d(p_cam)
        return np.stack(
            [self.fx * p_cam[:, 0] / p_cam[:, 2] + self.cx, self.fy * p_cam[:, 1] / p_cam[:, 2] + self.cy],
            axis=-1,
        )


@dataclass
class Render:
    """One rendered frame.

    points_cam: (H, W, 3) float32, camera optical frame, metres, NaN where invalid.
    rgb: (H, W, 3) uint8.
    geometry_ids: (H, W) int64, id of the surface hit (-1 for none).
    points_base_true: (H, W, 3) float64, noise-free hit points, base frame (inf where none).
    """

    points_cam: np.ndarray
    rgb: np.ndarray
    geometry_ids: np.ndarray
    points_base_true: np.ndarray


def cast(
    scene: o3d.t.geometry.RaycastingScene, T_base_cam: np.ndarray, camera: Camera
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray-cast ``scene`` (base frame) from a camera at ``T_base_cam`` (4, 4).

    Returns depth (H, W) (metres along the optical axis, inf for no hit), geometry ids (H, W) int64
    (-1 for no hit) and noise-free hit points (H, W, 3) in the base frame.
    """
    d_cam = camera.ray_directions_cam()
    d_base = d_cam @ T_base_cam[:3, :3].T
    origins = np.broadcast_to(T_base_cam[:3, 3], d_base.shape)
    rays = np.concatenate([origins, d_base], axis=-1).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
    depth = hit["t_hit"].numpy().astype(np.float64)
    ids = hit["geometry_ids"].numpy().astype(np.int64)
    ids[ids == INVALID_ID] = -1
    depth[ids < 0] = np.inf
    points_base = T_base_cam[:3, 3] + d_base * depth[..., None]
    return depth, ids, points_base


def add_sensor_effects(depth: np.ndarray, camera: Camera, rng: np.random.Generator) -> np.ndarray:
    """Noisy depth (H, W) with NaN for out-of-range, dropped and depth-edge pixels."""
    noisy = depth + rng.standard_normal(depth.shape) * camera.depth_sigma(
        np.where(np.isfinite(depth), depth, 0)
    )
    valid = np.isfinite(depth) & (depth >= camera.min_depth) & (depth <= camera.max_depth)
    # flying pixels at depth discontinuities are removed, as the RealSense post-processing does
    finite = np.where(np.isfinite(depth), depth, 1e3)
    edge = np.zeros(depth.shape, dtype=bool)
    dv = np.abs(np.diff(finite, axis=0)) > camera.edge_jump
    dh = np.abs(np.diff(finite, axis=1)) > camera.edge_jump
    edge[1:, :] |= dv
    edge[:-1, :] |= dv
    edge[:, 1:] |= dh
    edge[:, :-1] |= dh
    valid &= ~edge
    valid &= rng.random(depth.shape) >= camera.drop_rate
    return np.where(valid, noisy, np.nan)


def render(
    scene: o3d.t.geometry.RaycastingScene,
    colour_of: object,
    T_base_cam: np.ndarray,
    camera: Camera,
    rng: np.random.Generator,
) -> Render:
    """Render a frame: noisy organized camera-frame cloud and colours.

    colour_of: callable ``(geometry_ids (n,), points_base (n, 3)) -> (n, 3) uint8`` giving each hit
    its surface colour.
    """
    depth, ids, points_base = cast(scene, T_base_cam, camera)
    depth_noisy = add_sensor_effects(depth, camera, rng)
    points_cam = (camera.ray_directions_cam() * depth_noisy[..., None]).astype(np.float32)
    rgb = np.zeros((camera.height, camera.width, 3), dtype=np.uint8)
    hit = ids >= 0
    colours = colour_of(ids[hit], points_base[hit])  # type: ignore[operator]
    noise = rng.normal(0.0, 4.0, colours.shape)
    rgb[hit] = np.clip(colours.astype(np.float64) + noise, 0, 255).astype(np.uint8)
    return Render(points_cam=points_cam, rgb=rgb, geometry_ids=ids, points_base_true=points_base)


def look_at(eye_base: np.ndarray, target_base: np.ndarray, right_hint_base: np.ndarray) -> np.ndarray:
    """(4, 4) ``T_base_cam`` of an optical frame at ``eye`` looking at ``target``.

    The image x axis (right) is as close as possible to ``right_hint_base``.
    """
    z = np.asarray(target_base, float) - np.asarray(eye_base, float)
    z /= np.linalg.norm(z)
    x = np.asarray(right_hint_base, float) - np.dot(right_hint_base, z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, y, z], axis=1)
    T[:3, 3] = eye_base
    return T
