"""Synthetic calibration problems with known truth (tests and benchmarks)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .noise import camera_sigma, sample_noise


@dataclass
class Problem:
    """Ground truth and noisy measurements. p_cam: (n, 3) measured; p_cam_true: (n, 3) noise-free."""

    T_flange_cam: np.ndarray  # (4, 4)
    p_base: np.ndarray  # (3,)
    T_base_flange: np.ndarray  # (n, 4, 4)
    p_cam_true: np.ndarray  # (n, 3)
    p_cam: np.ndarray  # (n, 3) measured (depth read 1 / depth_scale long, noisy)
    sigma: np.ndarray  # (n, 3) noise std used, metres


def random_T_flange_cam(rng: np.random.Generator, offset_m: float = 0.08) -> np.ndarray:
    """(4, 4) camera mount: any rotation, translation up to ``offset_m`` per axis."""
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-offset_m, offset_m, 3)
    return T


def views_of(
    p_base: np.ndarray, n: int, rng: np.random.Generator, distance: tuple[float, float] = (0.3, 0.7),
    max_off_axis_deg: float = 40.0, max_image_offset_deg: float = 15.0,
) -> np.ndarray:  # fmt: skip
    """(n, 4, 4) T_base_cam looking down at ``p_base`` (base frame, metres) from random directions,
    distances and rolls, the blob off the image centre by up to ``max_image_offset_deg``."""
    theta = np.radians(rng.uniform(0.0, max_off_axis_deg, n))
    phi = rng.uniform(-np.pi, np.pi, n)
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
    eyes = p_base + rng.uniform(*distance, n)[:, None] * d
    z = -d
    x = np.cross(np.array([0.0, 0.0, 1.0]) + 1e-9, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    R_look = np.stack([x, np.cross(z, x), z], axis=2)
    roll = Rotation.from_rotvec(np.c_[np.zeros((n, 2)), rng.uniform(-np.pi, np.pi, n)]).as_matrix()
    off = Rotation.from_rotvec(
        np.c_[np.radians(rng.uniform(-max_image_offset_deg, max_image_offset_deg, (n, 2))), np.zeros(n)]
    ).as_matrix()
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R_look @ roll @ off
    T[:, :3, 3] = eyes
    return T


def make_problem(
    n: int,
    rng: np.random.Generator,
    T_flange_cam: np.ndarray | None = None,
    noise_scale: float = 1.0,
    robot_noise_m: float = 0.0,
    robot_noise_deg: float = 0.0,
    depth_scale: float = 1.0,
    scale_model: str = "depth_scale",
) -> Problem:
    """A problem of ``n`` views with D435-like noise (:mod:`sofia_calibrator.noise`) times ``noise_scale``.

    Beyond the camera noise: the reported flange poses are off by isotropic ``robot_noise_m``
    (metres, per axis) and ``robot_noise_deg`` (per axis, about the flange axes), and the camera's
    depth (``scale_model`` "depth_scale": z; "ray_scale": the whole point) reads 1 / ``depth_scale``
    long, so that ``depth_scale`` is the correction the calibration should find. ``sigma`` is then
    the camera noise plus the translation part of the robot noise (not the rotation part).
    """
    T_fc = random_T_flange_cam(rng) if T_flange_cam is None else T_flange_cam
    p_base = np.array([0.5, 0.0, 0.02]) + rng.uniform(-0.1, 0.1, 3)
    T_base_cam = views_of(p_base, n, rng)
    T_cam_base = np.linalg.inv(T_base_cam)
    p_cam_true = np.einsum("nij,j->ni", T_cam_base[:, :3, :3], p_base) + T_cam_base[:, :3, 3]
    T_base_flange = T_base_cam @ np.linalg.inv(T_fc)
    if robot_noise_m > 0 or robot_noise_deg > 0:  # the robot reports a slightly wrong pose
        T_base_flange[:, :3, 3] += rng.standard_normal((n, 3)) * robot_noise_m
        turn = Rotation.from_rotvec(np.radians(robot_noise_deg) * rng.standard_normal((n, 3))).as_matrix()
        T_base_flange[:, :3, :3] = T_base_flange[:, :3, :3] @ turn
    seen = p_cam_true / depth_scale if scale_model == "ray_scale" else p_cam_true / [1.0, 1.0, depth_scale]
    p_cam = seen + sample_noise(seen, rng, noise_scale)
    sigma = np.sqrt((camera_sigma(seen) * noise_scale) ** 2 + robot_noise_m**2)
    return Problem(T_fc, p_base, T_base_flange, p_cam_true, p_cam, sigma)
