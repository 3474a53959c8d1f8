"""The geometry of autonomous eye-to-hand calibration: a camera fixed in the cell, a ball on the
flange. :class:`sofia_arm.autocal.FixedAutocal` runs it.

Eye-to-hand is the eye-in-hand model with the flange poses inverted (``sofia_calibrator.eye_to_hand``):
``T_flange_cam`` reads as ``T_base_cam`` and ``p_base`` as the ball's centre in the flange frame, so
the planner's information (:mod:`sofia_arm.plan`) applies to ``T_flange_base`` unchanged.

Without a guess, the start: the flange moves a few centimetres along the base axes (the ball's
shift in the camera is the base shift turned by ``R_cam_base``: Wahba's problem gives the camera's
rotation) and turns a little about its own axes (then the ball's centre on the flange and the
camera's position are linear: :func:`rough_fixed`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation
from sofia_schemas.transforms import apply, invert

from . import plan
from .poses import Reach, in_image

START_SHIFT_M = 0.06  # the flange's moves along the base axes while finding the camera's rotation
START_TURN_DEG = 25.0  # and its turns about its own x and y axes
TILTS_DEG = (0.0, 20.0, 40.0)  # planned views: the flange turned from its start orientation ...
AZIMUTHS_DEG = np.arange(0, 360, 45)  # ... about horizontal axes of these directions ...
ROLLS_DEG = (-60.0, 0.0, 60.0)  # ... and about its own z axis
IMAGE_OFFSETS_DEG = np.array(
    [[0, 0], [14, 0], [-14, 0], [0, 10], [0, -10], [10, 8], [-10, -8], [10, -8], [-10, 8]]
)
MIN_FACING = 0.2  # cos of the angle between the flange->ball direction and the ball->camera one


def inverse_poses(T_base_flange: np.ndarray) -> np.ndarray:
    """(n, 4, 4) T_flange_base of flange poses (n, 4, 4): the eye-in-hand model's poses."""
    return np.asarray(invert(np.asarray(T_base_flange, dtype=np.float64)))


def start_moves(T_start: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(name, T_base_flange (4, 4)) of the start views: shifts along the base x, y, z axes, then
    turns about the flange's x and y axes (both signs)."""
    moves = []
    for i, name in enumerate("xyz"):
        T = T_start.copy()
        T[i, 3] += START_SHIFT_M
        moves.append((f"shift {name}", T))
    for axis, sign in (("x", 1), ("y", 1), ("x", -1), ("y", -1)):
        T = T_start.copy()
        T[:3, :3] = (
            T_start[:3, :3] @ Rotation.from_euler(axis, sign * START_TURN_DEG, degrees=True).as_matrix()
        )
        moves.append((f"turn {'+' if sign > 0 else '-'}{axis}", T))
    return moves


def rough_fixed(T_base_flange: np.ndarray, p_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(T_base_cam (4, 4), p_flange (3,)) from views (n, 4, 4) of the ball at p_cam (n, 3) (camera
    frame, m): the rotation from the pairs of views that share the first view's orientation (Wahba),
    then ``R_bf_i p_f - t_bc = R_bc p_cam_i - t_bf_i`` by linear least squares. None while the
    views cannot give it (fewer than 2 shifts, or no turn)."""
    T, p = np.asarray(T_base_flange, dtype=np.float64), np.asarray(p_cam, dtype=np.float64)
    same = np.array([np.allclose(Ti[:3, :3], T[0, :3, :3], atol=1e-3) for Ti in T])
    d_base, d_cam = T[same, :3, 3][1:] - T[0, :3, 3], p[same][1:] - p[0]
    if len(d_base) < 2 or np.linalg.matrix_rank(d_base, tol=1e-3) < 2 or same.all():
        return None
    R_bc = plan.wahba(d_base, d_cam)
    n = len(T)
    A = np.concatenate([T[:, :3, :3], np.broadcast_to(-np.eye(3), (n, 3, 3))], axis=2).reshape(3 * n, 6)
    b = (p @ R_bc.T - T[:, :3, 3]).reshape(3 * n)
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    T_bc = np.eye(4)
    T_bc[:3, :3], T_bc[:3, 3] = R_bc, x[3:]
    return T_bc, x[:3]


def fixed_candidates(
    T_base_cam: np.ndarray, p_flange: np.ndarray, R_base_start: np.ndarray, reach: Reach,
    distance_m: tuple[float, float], K: np.ndarray, image_size: tuple[int, int], margin_px: float,
) -> np.ndarray:  # fmt: skip
    """(m, 4, 4) flange poses putting the ball (p_flange (3,), flange frame) in front of the fixed
    camera (T_base_cam (4, 4)) at ``distance_m`` and the image offsets, the flange turned from
    its start orientation R_base_start (3, 3) by the tilts and rolls; kept when the flange is in
    the reach box, the ball in the image and the ball between the flange and the camera."""
    lo, hi = distance_m
    off = np.radians(IMAGE_OFFSETS_DEG)
    rays = np.c_[np.tan(off[:, 0]), np.tan(off[:, 1]), np.ones(len(off))]
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    p_cam = (np.linspace(lo, hi, 3)[:, None, None] * rays[None]).reshape(-1, 3)
    p_ball = apply(T_base_cam, p_cam)  # (k, 3) base frame
    turns = [np.eye(3)]
    for tilt in TILTS_DEG[1:]:
        for az in np.radians(AZIMUTHS_DEG):
            turns.append(
                Rotation.from_rotvec(np.radians(tilt) * np.array([np.cos(az), np.sin(az), 0.0])).as_matrix()
            )
    R_bf = np.array([R_base_start @ R @ Rotation.from_euler("z", r, degrees=True).as_matrix()
                     for R in turns for r in ROLLS_DEG])  # fmt: skip
    T = np.tile(np.eye(4), (len(p_ball), len(R_bf), 1, 1))
    T[:, :, :3, :3] = R_bf[None]
    T[:, :, :3, 3] = p_ball[:, None] - np.einsum("rij,j->ri", R_bf, p_flange)[None]
    T = T.reshape(-1, 4, 4)
    ball = np.repeat(p_ball, len(R_bf), axis=0)
    out = T[:, :3, :3] @ np.asarray(p_flange)
    to_cam = T_base_cam[:3, 3] - ball
    facing = np.einsum("ni,ni->n", out, to_cam) / (
        np.linalg.norm(out, axis=1) * np.linalg.norm(to_cam, axis=1) + 1e-12
    )
    keep = reach.in_box(T[:, :3, 3]) & reach.tool_clear(T) & (facing > MIN_FACING)
    keep &= in_image(np.repeat(p_cam, len(R_bf), axis=0), K, image_size, margin_px)
    return np.asarray(T[keep])
