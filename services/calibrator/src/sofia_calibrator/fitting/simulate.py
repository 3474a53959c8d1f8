"""Synthetic calibration problems with known truth (tests and benchmarks)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from scipy.spatial.transform import Rotation

from .noise import camera_sigma, sample_noise

P = TypeVar("P", "Problem", "EyeToHandProblem")  # a simulated eye-in-hand or eye-to-hand problem


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
    """A problem of ``n`` views with D435-like noise (:mod:`sofia_calibrator.fitting.noise`) times ``noise_scale``.

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


UNMODELLED_NOISE = ("student", "correlated", "depth3x", "scale")


def unmodelled_problem(kind: str, n: int, rng: np.random.Generator) -> Problem:
    """An eye-in-hand problem whose noise the solver does not assume (coverage and false-alarm checks).

    kind: "student" (camera and 1.5 mm robot noise Student-t with 3 degrees of freedom, unit
    variance scaled), "correlated" (robot error 2 mm per axis, AR(1) 0.8 between consecutive
    samples), "depth3x" (the camera's depth noise 3x its model, 1 mm robot noise) or "scale"
    (depth reads 1 / 0.95 long, 1.5 mm robot noise). The robot error is added to the reported
    flange translations; ``p_cam`` is the measured blob, camera frame, metres.
    """
    return _with_unmodelled(kind, lambda scale: make_problem(n, rng, noise_scale=0.0, depth_scale=scale), rng)


def _with_unmodelled(kind: str, make: Callable[[float], P], rng: np.random.Generator) -> P:
    """``make(depth_scale)``'s noise-free problem with the errors of ``kind`` added: camera errors
    on ``p_cam``, robot errors on the reported flange translations."""
    if kind not in UNMODELLED_NOISE:
        raise ValueError(f"kind must be one of {UNMODELLED_NOISE}, got {kind!r}")
    pr = make(0.95 if kind == "scale" else 1.0)
    camera_errors, robot_errors = unmodelled_errors(kind, pr.p_cam, rng)
    pr.T_base_flange[:, :3, 3] += robot_errors
    pr.p_cam = pr.p_cam + camera_errors
    return pr


def unmodelled_errors(
    kind: str, p_cam: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The errors of :func:`unmodelled_problem`'s ``kind`` for (n, 3) noise-free camera-frame
    points ``p_cam`` (metres): (n, 3) camera errors (camera frame) and (n, 3) robot translation
    errors (base frame), metres."""
    n = len(p_cam)
    camera = camera_sigma(p_cam)
    if kind == "student":
        e = rng.standard_t(3, p_cam.shape) / np.sqrt(3.0) * camera
        robot = rng.standard_t(3, (n, 3)) / np.sqrt(3.0) * 0.0015
    elif kind == "correlated":
        e = rng.standard_normal(p_cam.shape) * camera
        z = rng.standard_normal((n, 3)) * 0.002
        robot = np.empty_like(z)
        robot[0] = z[0]
        for i in range(1, n):  # AR(1): stationary 2 mm per axis
            robot[i] = 0.8 * robot[i - 1] + 0.6 * z[i]
    elif kind == "depth3x":
        e = rng.standard_normal(p_cam.shape) * camera * [1.0, 1.0, 3.0]
        robot = rng.standard_normal((n, 3)) * 0.001
    else:
        e = rng.standard_normal(p_cam.shape) * camera
        robot = rng.standard_normal((n, 3)) * 0.0015
    return e, robot


@dataclass
class EyeToHandProblem:
    """A fixed camera and a flange-mounted target, with truth. Metres."""

    T_base_cam: np.ndarray  # (4, 4)
    p_flange: np.ndarray  # (3,) target in the flange frame
    T_base_flange: np.ndarray  # (n, 4, 4) as reported (robot noise added)
    p_cam_true: np.ndarray  # (n, 3)
    p_cam: np.ndarray  # (n, 3) measured


def make_eye_to_hand(
    n: int, rng: np.random.Generator, noise_scale: float = 1.0, robot_noise_m: float = 0.0,
    depth_scale: float = 1.0, max_tilt_deg: float = 40.0,
) -> EyeToHandProblem:  # fmt: skip
    """A fixed camera 0.6-0.9 m from a workspace point, a target 5-12 cm from the flange, n flange
    poses tilted by up to ``max_tilt_deg`` about random axes (flange pointing down), the target
    within 12 cm of the workspace point. Noise as :func:`make_problem`."""
    look = np.array([0.5, 0.0, 0.3]) + rng.uniform(-0.05, 0.05, 3)
    T_base_cam = views_of(look, 1, rng, distance=(0.6, 0.9), max_off_axis_deg=50.0)[0]
    p_flange = np.r_[rng.uniform(-0.04, 0.04, 2), rng.uniform(0.05, 0.12)]
    down = Rotation.from_rotvec([np.pi, 0.0, 0.0])
    tilt = Rotation.from_rotvec(
        rng.standard_normal((n, 3)) / np.sqrt(3.0) * np.radians(max_tilt_deg) * rng.uniform(0.3, 1.0, (n, 1))
    )
    R = (down * tilt).as_matrix()
    q_base = look + rng.uniform(-0.12, 0.12, (n, 3))
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = q_base - R @ p_flange
    T_cam_base = np.linalg.inv(T_base_cam)
    p_cam_true = q_base @ T_cam_base[:3, :3].T + T_cam_base[:3, 3]
    T[:, :3, 3] += rng.standard_normal((n, 3)) * robot_noise_m
    seen = p_cam_true / [1.0, 1.0, depth_scale]
    return EyeToHandProblem(T_base_cam, p_flange, T, p_cam_true, seen + sample_noise(seen, rng, noise_scale))


def unmodelled_eye_to_hand(kind: str, n: int, rng: np.random.Generator) -> EyeToHandProblem:
    """An eye-to-hand problem (:func:`make_eye_to_hand`) with the errors of
    :func:`unmodelled_problem`'s ``kind``: camera errors on ``p_cam``, robot errors on the reported
    flange translations."""
    return _with_unmodelled(
        kind, lambda scale: make_eye_to_hand(n, rng, noise_scale=0.0, depth_scale=scale), rng
    )


def ball_cloud(centre: np.ndarray, radius: float, rng: np.random.Generator, n: int = 1500) -> np.ndarray:
    """(n, 3) a ball of ``radius`` at ``centre`` (3,) as a D435 at the origin sees it (camera frame,
    m): the surface within 70 deg of facing the camera, depth noise along the ray of 1 mm at 0.5 m
    growing with the square of the depth."""
    d = rng.standard_normal((20 * n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    pts = centre + radius * d
    facing = -np.einsum("ni,ni->n", d, pts / np.linalg.norm(pts, axis=1, keepdims=True))
    pts = pts[facing > np.cos(np.radians(70))][:n]
    return np.asarray(pts * (1 + rng.standard_normal(len(pts)) * 1e-3 * pts[:, 2] / 0.5**2)[:, None])
