"""Eye-to-hand: the camera fixed in the world, the target (a ball or blob) on the flange.

The observation ``p_cam_i = T_cam_base T_base_flange_i p_flange`` is the eye-in-hand one
(``p_cam_i = T_cam_flange T_flange_base_i p_base``) with the flange poses inverted: the same
solver, correction models, outlier test, diagnostics and uncertainty apply with
``T_flange_cam`` read as ``T_base_cam`` and ``p_base`` as the target's position in the flange
frame. The result's frames are the base's and the camera's, so its message, YAML, ROS launch line
and TF are those of ``T_base_cam``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sofia_schemas.transforms import as_transforms

from .errors import InputMismatch
from .fitting.calibrate import Calibration, calibrate

BASE_FRAME = "panda_link0"
CAMERA_FRAME = "camera_link_optical"
SETUPS = ("eye-in-hand", "eye-to-hand")


def flange_base_poses(T_base_flange: np.ndarray) -> np.ndarray:
    """(n, 4, 4) T_flange_base of (n, 4, 4) flange poses (rigid inverses, validated)."""
    T = np.asarray(as_transforms(T_base_flange, "T_base_flange"), dtype=np.float64)
    if T.ndim != 3:
        raise InputMismatch(f"T_base_flange must be (n, 4, 4), got {T.shape}")
    R_t = np.swapaxes(T[:, :3, :3], 1, 2)
    out = np.tile(np.eye(4), (len(T), 1, 1))
    out[:, :3, :3] = R_t
    out[:, :3, 3] = -np.einsum("nij,nj->ni", R_t, T[:, :3, 3])
    return out


def calibrate_eye_to_hand(
    p_cam: np.ndarray,
    T_base_flange: np.ndarray,
    *,
    parent_frame: str = BASE_FRAME,
    child_frame: str = CAMERA_FRAME,
    guess: np.ndarray | None = None,
    **options: Any,
) -> Calibration:
    """Calibrate a fixed camera from a flange-mounted target seen from n flange poses.

    p_cam: (n, 3) target, camera optical frame, metres. T_base_flange: (n, 4, 4) flange poses in
    the base frame. guess: optional (4, 4) T_base_cam. options: those of :func:`calibrate`.
    Returns a :class:`Calibration` whose ``T_flange_cam`` is T_base_cam (parent ``parent_frame``,
    the base) and whose ``p_base`` is the target in the flange frame (metres); ``map_to_base``
    then maps a camera point into the flange frame of its sample.
    """
    return calibrate(
        p_cam, flange_base_poses(T_base_flange), guess=guess, parent_frame=parent_frame,
        child_frame=child_frame, **options,
    )  # fmt: skip


def calibrate_setup(
    p_cam: np.ndarray, T_base_flange: np.ndarray, setup: str = "eye-in-hand", **options: Any
) -> Calibration:
    """:func:`calibrate` (eye-in-hand) or :func:`calibrate_eye_to_hand`, by ``setup``."""
    if setup not in SETUPS:
        raise InputMismatch(f"setup must be one of {SETUPS}, got {setup!r}")
    if setup == "eye-to-hand":
        return calibrate_eye_to_hand(p_cam, T_base_flange, **options)
    return calibrate(p_cam, T_base_flange, **options)
